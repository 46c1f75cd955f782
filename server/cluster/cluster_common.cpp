#include "server/cluster/cluster_common.h"

#include <grpc/grpc_security_constants.h>
#include <grpcpp/security/tls_certificate_provider.h>
#include <grpcpp/security/tls_certificate_verifier.h>
#include <grpcpp/security/tls_credentials_options.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <iterator>

#include "proto/convert/services.h"
#include "server/control/grpc_common.h"
#include "server/domain/auth.h"

namespace vsurg::server::cluster {

Status CheckToken(const std::string& token) {
  if (token.size() < 16)
    return InvalidArgument("cluster-token", "the cluster token must have at least 16 characters");
  return Status::Ok();
}

bool Authorized(const grpc::ServerContextBase& ctx, const std::string& token) {
  const auto& md = ctx.client_metadata();
  const auto it = md.find("authorization");
  if (it == md.end()) return false;
  const std::string expected = "Bearer " + token;
  const std::string_view got(it->second.data(), it->second.size());
  if (got.size() != expected.size()) return false;
  unsigned char diff = 0;  // constant time: the comparison does not stop at the first mismatch
  for (size_t i = 0; i < got.size(); ++i) diff |= static_cast<unsigned char>(got[i] ^ expected[i]);
  return diff == 0;
}

std::unique_ptr<grpc::ClientContext> CallContext(const std::string& token, double timeout_s) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->AddMetadata("authorization", "Bearer " + token);
  if (timeout_s > 0)
    ctx->set_deadline(std::chrono::system_clock::now() +
                      std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6)));
  return ctx;
}

namespace {

std::string Joined(std::vector<std::string> names) {
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  std::string out;
  for (const std::string& n : names) {
    if (n.empty()) continue;
    out += (out.empty() ? "" : ", ") + n;
  }
  return out.empty() ? "no name" : out;
}

// The client's check of the server it reached, after the TLS handshake has verified the chain up
// to the site's CA: the certificate must name the peer we meant to call. gRPC's own host-name
// check would compare the certificate with the address, which for a pod changes with every move.
class NameVerifier final : public grpc::experimental::ExternalCertificateVerifier {
 public:
  explicit NameVerifier(std::string name) : name_(std::move(name)) {}
  bool Verify(grpc::experimental::TlsCustomVerificationCheckRequest* request,
              std::function<void(grpc::Status)>, grpc::Status* sync_status) override {
    std::vector<std::string> names;
    for (const grpc::string_ref& n : request->dns_names()) names.emplace_back(n.data(), n.size());
    names.emplace_back(request->common_name().data(), request->common_name().size());
    if (std::find(names.begin(), names.end(), name_) != names.end())
      *sync_status = grpc::Status::OK;
    else
      *sync_status =
          grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                       "the peer's certificate names " + Joined(names) + ", not " + name_);
    return true;  // answered now
  }
  void Cancel(grpc::experimental::TlsCustomVerificationCheckRequest*) override {}

 private:
  std::string name_;
};

}  // namespace

Expected<TlsFiles> WatchTlsFiles(const ClusterOptions& o) {
  if (!o.tls()) return TlsFiles();
  struct File {
    const std::string& path;
    const char* flag;
    const char* marker;
    const char* kind;
  };
  const File files[] = {
      {o.tls_cert, "cluster-tls-cert", "-----BEGIN CERTIFICATE-----", "a PEM certificate"},
      {o.tls_key, "cluster-tls-key", "PRIVATE KEY-----", "a PEM private key"},
      {o.tls_ca, "cluster-tls-ca", "-----BEGIN CERTIFICATE-----",
       "the site's PEM CA certificates"}};
  for (const File& f : files) {
    if (f.path.empty())
      return InvalidArgument(f.flag,
                             "mutual TLS needs this process's certificate, its key and the "
                             "site's CA bundle: all three files");
    std::ifstream in(f.path);
    if (!in) return InvalidArgument(f.flag, "cannot read " + f.path);
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (text.find(f.marker) == std::string::npos)
      return InvalidArgument(f.flag, f.path + " does not hold " + f.kind);
  }
  if (!ClusterOptions::kTlsRefreshS.Contains(o.tls_refresh_s))
    return InvalidArgument("cluster-tls-refresh", ClusterOptions::kTlsRefreshS.Must() + " seconds");
  if (o.control_name.empty() || o.control_name.size() > 253)
    return InvalidArgument("cluster-control-name", "a name of 1 to 253 characters is required");
  return TlsFiles(std::make_shared<grpc::experimental::FileWatcherCertificateProvider>(
      o.tls_key, o.tls_cert, o.tls_ca, static_cast<unsigned>(o.tls_refresh_s)));
}

std::shared_ptr<grpc::Channel> Channel(const std::string& target, const TlsFiles& tls_files,
                                       const std::string& peer_name) {
  grpc::ChannelArguments args;
  // Reconnect fast after a replica or a node comes back (the default backs off to 2 minutes):
  // the first retry after 100 ms, then at most every second. gRPC also takes the "minimum
  // reconnect backoff" as each connection attempt's shortest deadline: at 100 ms a handshake
  // that took longer on a loaded machine was shut down and every call waiting on the new channel
  // failed at once ("failed to connect to all addresses; tcp handshaker shutdown": under ASan, a
  // burst of 15 Creates lost whole nodes to it about one run in eight). 2 s, within the
  // heartbeat timeout.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 2000);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  args.SetMaxReceiveMessageSize(kMaxInternalMessageBytes);
  args.SetMaxSendMessageSize(kMaxInternalMessageBytes);
  std::string t = target;
  if (target.find(',') != std::string::npos && target.find(':') != std::string::npos &&
      target.rfind("ipv4:", 0) != 0 && target.rfind("dns:", 0) != 0)
    t = "ipv4:" + target;  // several literal addresses: one channel over all of them
  if (!tls_files) return grpc::CreateCustomChannel(t, grpc::InsecureChannelCredentials(), args);
  // The name the client asks for in the handshake (SNI) is the peer's name, not its address.
  args.SetSslTargetNameOverride(peer_name);
  grpc::experimental::TlsChannelCredentialsOptions tls;
  tls.set_certificate_provider(tls_files);
  tls.watch_root_certs();
  tls.watch_identity_key_cert_pairs();
  tls.set_verify_server_certs(true);
  tls.set_check_call_host(false);
  tls.set_certificate_verifier(
      grpc::experimental::ExternalCertificateVerifier::Create<NameVerifier>(peer_name));
  return grpc::CreateCustomChannel(t, grpc::experimental::TlsCredentials(tls), args);
}

Expected<std::shared_ptr<grpc::ServerCredentials>> ServerCredentials(const ClusterOptions& o,
                                                                     const TlsFiles& tls_files) {
  if (Status s = CheckToken(o.token); !s.ok()) return s.error();
  if (o.tls()) {
    if (!tls_files) return InvalidArgument("cluster-tls-cert", "the TLS files are not watched");
    grpc::experimental::TlsServerCredentialsOptions tls(tls_files);
    tls.watch_root_certs();
    tls.watch_identity_key_cert_pairs();
    tls.set_cert_request_type(GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
    return grpc::experimental::TlsServerCredentials(tls);
  }
  if (!IsLoopbackHost(o.listen) && !o.allow_insecure)
    return InvalidArgument("cluster-listen",
                           "the internal API is plaintext: on loopback only, unless it runs with "
                           "mutual TLS (the cluster TLS files) or the site's network is private "
                           "(allow insecure explicitly; docs/SCALING.md)");
  return grpc::InsecureServerCredentials();
}

std::vector<std::string> PeerNames(const grpc::ServerContextBase& ctx) {
  std::vector<std::string> out;
  const auto auth = ctx.auth_context();
  if (!auth) return out;
  // RFC 6125 §6.4.4: a certificate with subject alternative names is named by them alone; its
  // common name is read only when it has none (a SAN of sim-rogue with a CN of sim-0 is not
  // sim-0).
  for (const char* property : {GRPC_X509_SAN_PROPERTY_NAME, GRPC_X509_CN_PROPERTY_NAME}) {
    for (const grpc::string_ref& v : auth->FindPropertyValues(property))
      out.emplace_back(v.data(), v.size());
    if (!out.empty()) break;
  }
  return out;
}

grpc::Status CheckPeer(const grpc::ServerContextBase& ctx, const ClusterOptions& o,
                       const std::string& name, const std::string& what) {
  if (!o.tls()) return grpc::Status::OK;
  const std::vector<std::string> names = PeerNames(ctx);
  if (std::find(names.begin(), names.end(), name) != names.end()) return grpc::Status::OK;
  return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                      "the caller's certificate names " + Joined(names) + ", not " + what);
}

Expected<std::unique_ptr<grpc::Server>> StartHealthServer(const ClusterOptions& o, int* port) {
  *port = 0;
  if (o.health_listen.empty()) return std::unique_ptr<grpc::Server>();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  builder.AddListeningPort(o.health_listen, grpc::InsecureServerCredentials(), port);
  auto server = builder.BuildAndStart();
  if (!server || *port == 0)
    return Error{ErrorCode::kUnavailable, "cannot listen on " + o.health_listen,
                 "cluster-health-listen"};
  return server;
}

// Plain POSIX rather than Asio: one connect with a deadline on the caller's thread, no
// io_context to run; the name is resolved by getaddrinfo, which may block on DNS (the caller
// is the watchdog's prober thread, which nothing else waits for).
Listening ProbeListening(const std::string& host_port, double timeout_s) {
  const auto colon = host_port.rfind(':');
  if (colon == std::string::npos || colon + 1 == host_port.size()) return Listening::kUnknown;
  std::string host = host_port.substr(0, colon);
  const std::string port = host_port.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0 || !found)
    return Listening::kUnknown;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6));
  bool all_refused = true;
  Listening out = Listening::kUnknown;
  for (addrinfo* a = found; a && out != Listening::kYes; a = a->ai_next) {
    const int fd =
        ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      all_refused = false;
      continue;
    }
    int err = ::connect(fd, a->ai_addr, a->ai_addrlen) == 0 ? 0 : errno;
    if (err == EINPROGRESS) {
      pollfd p{fd, POLLOUT, 0};
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      int ready;
      do {
        ready = ::poll(&p, 1, static_cast<int>(std::max<int64_t>(0, left.count())));
      } while (ready < 0 && errno == EINTR);
      err = ETIMEDOUT;
      if (ready > 0) {
        socklen_t len = sizeof(err);
        if (::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) != 0) err = errno;
      }
    }
    ::close(fd);
    if (err == 0) out = Listening::kYes;
    if (err != ECONNREFUSED) all_refused = false;
  }
  freeaddrinfo(found);
  if (out == Listening::kYes) return out;
  return all_refused ? Listening::kRefused : Listening::kUnknown;
}

Error FromGrpc(const grpc::Status& s, const std::string& what) {
  ErrorCode code = ErrorCode::kIoError;
  switch (s.error_code()) {
    case grpc::StatusCode::INVALID_ARGUMENT:
      code = ErrorCode::kInvalidArgument;
      break;
    case grpc::StatusCode::NOT_FOUND:
      code = ErrorCode::kNotFound;
      break;
    case grpc::StatusCode::ALREADY_EXISTS:
      code = ErrorCode::kAlreadyExists;
      break;
    case grpc::StatusCode::FAILED_PRECONDITION:
      code = ErrorCode::kFailedPrecondition;
      break;
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      code = ErrorCode::kResourceExhausted;
      break;
    case grpc::StatusCode::UNAUTHENTICATED:
      code = ErrorCode::kUnauthenticated;
      break;
    case grpc::StatusCode::PERMISSION_DENIED:
      code = ErrorCode::kPermissionDenied;
      break;
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
    case grpc::StatusCode::CANCELLED:
      code = ErrorCode::kUnavailable;
      break;
    default:
      break;
  }
  // The node's message already names the field ("field: message").
  return Error{code, what + ": " + s.error_message(), ""};
}

db::SessionRecord FromProto(const v1::Session& s) {
  db::SessionRecord r;
  r.id = static_cast<int64_t>(s.id());
  r.trainee = s.trainee();
  r.scene = s.scene();
  r.state = convert::FromProto(s.state()).value_or(SessionState::kAborted);
  r.created_us = s.created_us();
  r.started_us = s.started_us();
  r.ended_us = s.ended_us();
  r.end_reason = s.end_reason();
  return r;
}

db::NodeRecord FromProto(const v1::NodeHeartbeat& beat, int64_t received_us) {
  db::NodeRecord n;
  n.name = beat.name();
  n.grpc_address = beat.grpc_address();
  n.udp_host = beat.udp_host();
  n.udp_port = static_cast<int>(beat.udp_port());
  n.capacity = beat.capacity();
  n.sessions = beat.sessions();
  n.cpu = beat.cpu();
  n.draining = beat.draining();
  n.started_us = beat.started_us();
  n.instance = beat.instance();
  n.epoch = beat.epoch();
  n.heartbeat_us = received_us;
  return n;
}

CreatedSession FromProto(const v1::NodeSession& s) {
  CreatedSession c;
  c.record = FromProto(s.session());
  c.udp_host = s.udp_host();
  c.udp_port = static_cast<uint16_t>(s.udp_port());
  const std::string& key = s.session_key();
  std::copy_n(key.begin(), std::min(key.size(), c.key.size()), c.key.begin());
  if (s.second_channel() != 0 && s.second_key().size() == c.second_key.size()) {
    c.second_channel = s.second_channel();
    std::copy_n(s.second_key().begin(), c.second_key.size(), c.second_key.begin());
  }
  c.channel = s.channel();
  if (s.has_surface()) {
    // A node's surface is checked as a station checks it; one that does not read is left out
    // (the station then renders the surface ahead from the answers alone).
    auto surface = convert::FromProto(s.surface());
    if (surface.ok()) c.surface = *surface;
  }
  if (s.has_needle()) {  // likewise: a needle model the station would refuse is left out
    auto needle = convert::FromProto(s.needle());
    if (needle.ok()) c.needle = *needle;
  }
  if (s.has_blade()) {  // and a blade
    auto blade = convert::FromProto(s.blade());
    if (blade.ok()) c.blade = *blade;
  }
  return c;
}

void ToProto(const CreatedSession& c, bool with_key, v1::NodeSession* out) {
  grpcapi::ToProto(c.record, out->mutable_session());
  out->set_udp_host(c.udp_host);
  out->set_udp_port(c.udp_port);
  if (with_key) out->set_session_key(std::string(c.key.begin(), c.key.end()));
  out->set_channel(c.channel);
  if (with_key && c.second_channel != 0) {
    out->set_second_channel(c.second_channel);
    out->set_second_key(std::string(c.second_key.begin(), c.second_key.end()));
  }
  if (c.surface) convert::ToProto(*c.surface, out->mutable_surface());
  if (c.needle) convert::ToProto(*c.needle, out->mutable_needle());
  if (c.blade) convert::ToProto(*c.blade, out->mutable_blade());
}

}  // namespace vsurg::server::cluster
