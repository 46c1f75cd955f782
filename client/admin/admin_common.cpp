#include "client/admin/commands.h"

#include <openssl/evp.h>

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/file.h"
#include "common/core/time.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "db/vocabulary.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::admin {

namespace v1 = vsurg::v1;

int Usage(std::ostream& err, const std::string& cmd, const std::string& field,
          const std::string& msg) {
  return vsurg::cli::UsageError(err, cmd,
                                vsurg::Error{vsurg::ErrorCode::kInvalidArgument, msg, field});
}

std::optional<int> Begin(ArgParser& p, const Args& args, std::ostream& out, std::ostream& err,
                         Remote& remote) {
  client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return rc;
  auto r = client::ConnectRemote(p);
  if (!r.ok()) return Usage(err, p.command(), r.error().field, r.error().message);
  remote = std::move(r).value();
  return std::nullopt;
}

int RpcError(std::ostream& err, const std::string& cmd, const grpc::Status& s) {
  return client::ReportRpcError(err, cmd, s);
}

std::string Fixed(const nlohmann::json& v, int digits) {
  if (!v.is_number()) return "n/a";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v.get<double>());
  return buf;
}

// The coil-spring paper's table of one subject's report (Fig. 12-14: M_j, s_j, N) with the
// agreement.
}  // namespace vsurg::admin
