// vsurg-admin: the administrators' tool, a pure gRPC client: every command goes through the
// server's AdminService / EvaluationService / SessionService with a bearer token (--token,
// --token-file or $VSURG_TOKEN), and every call has a deadline. It never opens the store file:
// the operations that need the file (init, offline export, backup to a path) are vsurg-server's
// subcommands. The commands: client/admin/commands.h.
#include <iostream>
#include <string>
#include <vector>

#include "client/admin/commands.h"

namespace {

using namespace vsurg::admin;  // NOLINT: this file only dispatches to the commands

const char* kHelp =
    "usage: vsurg-admin <command> [options]\n\n"
    "commands:\n"
    "  user-add      create a user (trainee, instructor, evaluator, admin)\n"
    "  users         list users\n"
    "  token-issue   issue a token for a user (printed once)\n"
    "  token-revoke  revoke a user's tokens\n"
    "  weights-put   store a weight set\n"
    "  scenes        the scenes the server runs\n"
    "  sessions      sessions with the scoring loop's trial metrics\n"
    "  import        submit evaluations from a ratings CSV\n"
    "  report        weighted evaluation report (the coil-spring paper eq. 9-11), or --training\n"
    "  export        export evaluations: --format csv|jsonl|xapi --out FILE\n"
    "  backup        online backup of the server's store\n\n"
    "Remote commands take --server HOST:PORT and a token (--token, --token-file, $VSURG_TOKEN).\n";

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::vector<std::string> all(argv + 1, argv + argc);
    if (all.empty()) {
      std::cerr << "vsurg-admin: a command is required (see --help)\n";
      return kExitUsage;
    }
    const std::string& cmd = all[0];
    const std::vector<std::string> rest(all.begin() + 1, all.end());
    auto& out = std::cout;
    auto& err = std::cerr;
    if (cmd == "--help" || cmd == "-h" || cmd == "help") return out << kHelp, 0;
    if (cmd == "init") {
      // Moved: vsurg-admin is a pure gRPC client and never opens the store file.
      err << "vsurg-admin: 'init' works on the store file and moved to the server: "
             "vsurg-server init --db FILE [--name admin]\n";
      return kExitUsage;
    }
    if (cmd == "user-add") return UserAdd(rest, out, err);
    if (cmd == "token-issue") return Token(rest, out, err, false);
    if (cmd == "token-revoke") return Token(rest, out, err, true);
    if (cmd == "import") return Import(rest, out, err);
    if (cmd == "report") return Report(rest, out, err);
    if (cmd == "export") return Export(rest, out, err);
    if (cmd == "scenes" || cmd == "sessions") return Scenes(rest, out, err, cmd);
    if (cmd == "users") return Users(rest, out, err);
    if (cmd == "backup") return Backup(rest, out, err);
    if (cmd == "weights-put") return WeightsPut(rest, out, err);
    std::cerr << "vsurg-admin: unknown command '" << cmd << "' (see --help)\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "vsurg-admin: fatal: " << e.what() << "\n";
    return kExitRuntime;
  }
}
