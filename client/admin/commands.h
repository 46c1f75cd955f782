// vsurg-admin's commands, one family per file (client/admin/): user_commands.cpp (user-add,
// users, token-issue, token-revoke), evaluation_commands.cpp (import, report, weights-put),
// data_commands.cpp (export, backup), session_commands.cpp (scenes, sessions); admin_main.cpp
// dispatches. What they share is below. Private to client/admin/.
#pragma once

#include <grpcpp/grpcpp.h>

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "client/net/remote.h"
#include "common/core/args.h"

namespace vsurg::admin {

using Args = std::vector<std::string>;
using cli::ArgParser;
using Kind = ArgParser::Kind;
using cli::kExitRuntime;
using cli::kExitUsage;
using cli::ParseOrExit;
using client::Remote;

// One line "COMMAND: FIELD: message" on `err`; returns kExitUsage.
int Usage(std::ostream& err, const std::string& cmd, const std::string& field,
          const std::string& msg);
// Adds the remote options, parses and connects. Returns the exit code to stop with (help
// printed, or a usage error), or nothing when the command should go on with `remote`.
std::optional<int> Begin(ArgParser& p, const Args& args, std::ostream& out, std::ostream& err,
                         Remote& remote);
int RpcError(std::ostream& err, const std::string& cmd, const grpc::Status& s);
// A number with `digits` decimals, "-" for null (reports' undefined figures).
std::string Fixed(const nlohmann::json& v, int digits = 3);

int UserAdd(const Args& args, std::ostream& out, std::ostream& err);
int Token(const Args& args, std::ostream& out, std::ostream& err, bool revoke);
int Users(const Args& args, std::ostream& out, std::ostream& err);
int Import(const Args& args, std::ostream& out, std::ostream& err);
int Report(const Args& args, std::ostream& out, std::ostream& err);
int WeightsPut(const Args& args, std::ostream& out, std::ostream& err);
int Export(const Args& args, std::ostream& out, std::ostream& err);
int Backup(const Args& args, std::ostream& out, std::ostream& err);
int Scenes(const Args& args, std::ostream& out, std::ostream& err, const std::string& cmd);

}  // namespace vsurg::admin
