// vsurg-server's subcommands on the store file, for an administrator at the server's machine:
//
//   vsurg-server init   --db FILE [--name admin]   create the store and its first administrator
//   vsurg-server export --db FILE --out OUT [...]  offline export (read-only open)
//   vsurg-server backup --db FILE --out OUT        consistent copy (read-only open)
//
// init is the one operation that must create and migrate the file (there is no administrator to
// call the server yet); export and backup open it read-only (db::Store::OpenReadOnly): they never
// create a mistyped path, never migrate, and are safe beside a live server, whose writer they
// never block. Everything else is vsurg-admin's, over gRPC.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace vsurg::server {

bool IsStoreCommand(const std::string& name);
// Exit codes: 0 done, 1 failed at run time, 2 bad arguments.
int RunStoreCommand(const std::string& name, const std::vector<std::string>& args,
                    std::ostream& out, std::ostream& err);

}  // namespace vsurg::server
