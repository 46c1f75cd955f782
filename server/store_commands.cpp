#include "server/store_commands.h"

#include <filesystem>
#include <ostream>

#include "common/core/args.h"
#include "common/core/file.h"
#include "common/core/time.h"
#include "db/store.h"

namespace vsurg::server {
namespace {

using cli::ArgParser;
using Kind = ArgParser::Kind;

using cli::kExitRuntime;
using cli::kExitUsage;
using cli::ParseOrExit;

int Usage(std::ostream& err, const std::string& cmd, const std::string& field,
          const std::string& msg) {
  return cli::UsageError(err, cmd, Error{ErrorCode::kInvalidArgument, msg, field});
}

int Fail(std::ostream& err, const std::string& cmd, const Error& e) {
  cli::UsageError(err, cmd, e);
  return kExitRuntime;
}

int Init(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-server init",
              "Creates the store (when missing) and its first administrator, and prints the\n"
              "administrator's token once on stdout. Refuses when an administrator exists.");
  p.Option("db", Kind::kString, "SQLite database file", true)
      .Option("name", Kind::kString, "administrator user name", false, "admin");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto store = db::Store::Open({.path = p.String("db")});
  if (!store.ok()) return Usage(err, p.command(), "--db", store.error().message);
  auto token = (*store)->InitAdmin(p.String("name"));
  if (!token.ok()) return Fail(err, p.command(), token.error());
  out << *token << "\n";
  err << p.command() << ": administrator '" << p.String("name")
      << "' created; the token above is shown only once\n";
  return 0;
}

int Export(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-server export",
              "Exports the stored evaluations from the store file, opened read-only (safe beside\n"
              "a running server): one row per evaluator, subject and index (CSV per RFC 4180,\n"
              "ISO-8601 UTC times, or JSON lines), or one xAPI statement per submission. Written\n"
              "to a temporary file and renamed when complete.");
  p.Option("db", Kind::kString, "SQLite database file (never created or migrated)", true)
      .Option("format", Kind::kString, "csv, jsonl or xapi", false, "csv")
      .Option("out", Kind::kString, "output file", true)
      .Option("from", Kind::kString, "submitted at or after (2026-11-21 or ...T10:00:00Z)")
      .Option("to", Kind::kString, "submitted before")
      .Option("trainee", Kind::kString, "only this trainee (trainee subjects and their sessions)")
      .Option("session", Kind::kInt, "only this session");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const auto format = db::ParseExportFormat(p.String("format"));
  if (!format) return Usage(err, p.command(), "--format", "csv, jsonl or xapi");
  db::ExportFilter f;
  for (const char* opt : {"from", "to"}) {
    if (!p.Has(opt)) continue;
    auto t = ParseIsoUtc(p.String(opt), std::string("--") + opt);
    if (!t.ok()) return Usage(err, p.command(), t.error().field, t.error().message);
    (std::string(opt) == "from" ? f.from_us : f.to_us) = *t;
  }
  if (p.Has("trainee")) f.trainee = p.String("trainee");
  if (p.Has("session")) {
    if (p.Int("session") <= 0) return Usage(err, p.command(), "--session", "a session id > 0");
    f.session = p.Int("session");
  }
  auto store = db::Store::OpenReadOnly(p.String("db"));
  if (!store.ok()) return Usage(err, p.command(), "--db", store.error().message);
  auto file = AtomicFile::Open(p.String("out"), "--out");
  if (!file.ok()) return Usage(err, p.command(), "--out", file.error().message);
  Status s =
      (*store)->Export(f, *format, [&](std::string_view chunk) { return file->Write(chunk); });
  if (s.ok()) s = file->Commit();
  if (!s.ok()) return Fail(err, p.command(), s.error());
  err << p.command() << ": wrote " << file->bytes() << " bytes to " << p.String("out") << "\n";
  return 0;
}

int Backup(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-server backup",
              "Copies the store file to a new file, consistently, while a server may be running\n"
              "(SQLite's online backup from a read-only connection). Never overwrites.");
  p.Option("db", Kind::kString, "SQLite database file (never created or migrated)", true)
      .Option("out", Kind::kString, "the new file", true);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const std::string dest = p.String("out");
  std::error_code ec;
  if (std::filesystem::symlink_status(dest, ec).type() != std::filesystem::file_type::not_found)
    return Usage(err, p.command(), "--out", "will not overwrite " + dest);
  auto store = db::Store::OpenReadOnly(p.String("db"));
  if (!store.ok()) return Usage(err, p.command(), "--db", store.error().message);
  if (Status s = (*store)->Backup(dest); !s.ok()) {
    std::filesystem::remove(dest, ec);
    return Fail(err, p.command(), s.error());
  }
  err << p.command() << ": wrote " << dest << "\n";
  return 0;
}

}  // namespace

bool IsStoreCommand(const std::string& name) {
  return name == "init" || name == "export" || name == "backup";
}

int RunStoreCommand(const std::string& name, const std::vector<std::string>& args,
                    std::ostream& out, std::ostream& err) {
  if (name == "init") return Init(args, out, err);
  if (name == "export") return Export(args, out, err);
  if (name == "backup") return Backup(args, out, err);
  err << "vsurg-server: unknown command '" << name << "'\n";
  return kExitUsage;
}

}  // namespace vsurg::server
