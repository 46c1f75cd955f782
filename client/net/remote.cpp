#include "client/net/remote.h"

#include <grpcpp/grpcpp.h>

#include <cctype>
#include <chrono>
#include <cstdlib>

#include "common/core/file.h"

namespace vsurg::client {

using Kind = cli::ArgParser::Kind;

void AddRemoteOptions(cli::ArgParser& p) {
  p.Option("server", Kind::kString, "gRPC address host:port", false, "127.0.0.1:50051")
      .Option("token", Kind::kString, "bearer token (default: $VSURG_TOKEN)")
      .Option("token-file", Kind::kString, "file holding the bearer token")
      .Option("tls-ca", Kind::kString, "PEM CA certificate: use TLS and trust this CA")
      .Option("timeout", Kind::kDouble, "deadline per call, s", false, "10");
}

void Remote::Prepare(grpc::ClientContext& ctx, double timeout) const {
  ctx.AddMetadata("authorization", "Bearer " + token);
  ctx.set_deadline(
      std::chrono::system_clock::now() +
      std::chrono::milliseconds(static_cast<int64_t>(1000 * (timeout > 0 ? timeout : timeout_s))));
}

Expected<Remote> ConnectRemote(const cli::ArgParser& p) {
  Remote r;
  if (p.Has("token")) {
    r.token = p.String("token");
  } else if (p.Has("token-file")) {
    auto t = ReadTextFile(p.String("token-file"), "--token-file");
    if (!t.ok()) return t.error();
    r.token = *t;
  } else if (const char* env = std::getenv("VSURG_TOKEN")) {
    r.token = env;
  }
  while (!r.token.empty() && std::isspace(static_cast<unsigned char>(r.token.back())))
    r.token.pop_back();
  if (r.token.empty())
    return InvalidArgument("--token",
                           "a token is required (--token, --token-file or $VSURG_TOKEN)");
  r.timeout_s = p.Double("timeout");
  if (!(r.timeout_s > 0 && r.timeout_s <= 3600))
    return InvalidArgument("--timeout", "must be within (0, 3600] s");
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (p.Has("tls-ca")) {
    auto ca = ReadTextFile(p.String("tls-ca"), "--tls-ca");
    if (!ca.ok()) return ca.error();
    grpc::SslCredentialsOptions o;
    o.pem_root_certs = *ca;
    creds = grpc::SslCredentials(o);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  r.address = p.String("server");
  r.credentials = creds;
  r.channel = MakeChannel(r.address, creds);
  return r;
}

void Remote::Renew() {
  if (!address.empty()) channel = MakeChannel(address, credentials);
}

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& address,
                                           std::shared_ptr<grpc::ChannelCredentials> credentials) {
  // gRPC's default reconnect backoff grows to two minutes: a station whose server restarted
  // would wait that long. Stations retry on their own schedule; keep the channel's at ≤ 1 s.
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  // A call that met a lost control replica (UNAVAILABLE before any answer) is sent again, to the
  // next replica of the list: gRPC's own retry policy. Safe for our calls: submissions carry
  // idempotency keys, and the rest are reads or state changes that say what they found.
  args.SetServiceConfigJSON(R"({"methodConfig": [{
      "name": [{"service": "vsurg.v1.SessionService"}, {"service": "vsurg.v1.MonitorService"},
               {"service": "vsurg.v1.EvaluationService"}, {"service": "vsurg.v1.AdminService"}],
      "retryPolicy": {"maxAttempts": 5, "initialBackoff": "0.05s", "maxBackoff": "0.5s",
                      "backoffMultiplier": 2, "retryableStatusCodes": ["UNAVAILABLE"]}}]})");
  // Several control replicas "host:port,host:port" (literal addresses): one channel over the
  // list, pick_first, so a call after a replica is lost goes to the next one.
  const bool list = address.find(',') != std::string::npos &&
                    address.find("://") == std::string::npos && address.rfind("ipv4:", 0) != 0 &&
                    address.rfind("ipv6:", 0) != 0;
  return grpc::CreateCustomChannel(list ? "ipv4:" + address : address,
                                   credentials ? credentials : grpc::InsecureChannelCredentials(),
                                   args);
}

int ReportRpcError(std::ostream& err, const std::string& command, const grpc::Status& s) {
  err << command << ": " << s.error_message() << " (gRPC " << static_cast<int>(s.error_code())
      << ")\n";
  return 1;
}

}  // namespace vsurg::client
