// What the two roles share: the cluster token on calls, channels to the other side, the status
// mapping back from gRPC, and the internal messages to and from our types. Private to
// server/cluster/.
#pragma once

#include <grpcpp/grpcpp.h>
#include <grpcpp/security/tls_certificate_provider.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "server/cluster/cluster.h"
#include "vsurg/v1/cluster.grpc.pb.h"

namespace vsurg::server::cluster {

namespace v1 = vsurg::v1;

// A token a site may use: at least 16 characters (it is a shared secret between processes).
Status CheckToken(const std::string& token);
// Whether the call's `authorization` metadata carries `token` (compared in constant time).
bool Authorized(const grpc::ServerContextBase& ctx, const std::string& token);
// A client context with the token and a deadline `timeout_s` from now (none for timeout_s ≤ 0:
// a stream that lasts until it is cancelled).
std::unique_ptr<grpc::ClientContext> CallContext(const std::string& token, double timeout_s);
// The watcher of a process's TLS files (null without TLS): a gRPC thread that reads them every
// tls_refresh_s, shared by the process's server and channels, gone with the last of them. Refused
// unless the TLS options hold together: the three files all or none, each readable and holding
// PEM of its kind, a refresh period of 1 s to a day, a control name.
using TlsFiles = std::shared_ptr<grpc::experimental::CertificateProviderInterface>;
Expected<TlsFiles> WatchTlsFiles(const ClusterOptions& o);
// A channel to `target`: "host:port", or several "host:port,host:port" tried in turn
// (pick_first over the list: a client fails over to the next replica). With TLS files, it
// presents this process's certificate and accepts only a peer whose certificate the site's CA
// signed and that names `peer_name` (a node's name, or the control replicas' name); the address
// itself is not checked against the certificate (pods move; the name is what the site knows
// them by).
// The internal API's largest message, both ways: a live session's handoff (live migration:
// NodeService.Adopt, ClusterService.Migrate) is its simulation's state and its record so far,
// deflated; a forearm's after a minute is about 1 MB, its worst case (the record's 96 surface
// frames) under 4 MB before deflating, gRPC's default limit.
inline constexpr int kMaxInternalMessageBytes = 32 << 20;

std::shared_ptr<grpc::Channel> Channel(const std::string& target, const TlsFiles& tls,
                                       const std::string& peer_name);
// Listening credentials: mutual TLS when configured (a client certificate the site's CA signed is
// required), `tls` being WatchTlsFiles(o)'s; otherwise plaintext, on loopback unless
// allow_insecure (SCALING.md).
Expected<std::shared_ptr<grpc::ServerCredentials>> ServerCredentials(const ClusterOptions& o,
                                                                     const TlsFiles& tls);
// The names the caller's certificate carries: its subject alternative names, then its common
// name. Empty over plaintext.
std::vector<std::string> PeerNames(const grpc::ServerContextBase& ctx);
// Over plaintext OK (the token is all there is); with TLS OK when the caller's certificate names
// `name`, else PERMISSION_DENIED saying what it names instead (`what`: "node sim-0").
grpc::Status CheckPeer(const grpc::ServerContextBase& ctx, const ClusterOptions& o,
                       const std::string& name, const std::string& what);
// With o.health_listen set: a plaintext gRPC server there with the standard health service only
// (what Kubernetes' probes reach when the internal port wants a client certificate). Null when
// not configured. `port`: the port it bound.
Expected<std::unique_ptr<grpc::Server>> StartHealthServer(const ClusterOptions& o, int* port);

// Whether a process listens at "host:port" (a node's gRPC address), by one TCP connect that
// waits at most `timeout_s`. kRefused only when every address of the host refused the
// connection (nothing listens there: the node's process is gone, and its sessions with it);
// kUnknown for a timeout, an unreachable host or a name that does not resolve (a machine that
// is gone or cut off answers nothing: only the heartbeat timeout decides for it).
enum class Listening { kYes, kRefused, kUnknown };
Listening ProbeListening(const std::string& host_port, double timeout_s);

// A failed internal call as our Error (UNAVAILABLE and DEADLINE_EXCEEDED: kUnavailable).
Error FromGrpc(const grpc::Status& s, const std::string& what);

db::SessionRecord FromProto(const v1::Session& s);
// A node's heartbeat (or acquisition) as its registry row, stamped `received_us` on the receiving
// replica's clock: a node's own clock never decides its liveness. The replicas compare each
// other's stamps, so their clocks must agree within the lease margin (NTP; docs/SCALING.md).
db::NodeRecord FromProto(const v1::NodeHeartbeat& beat, int64_t received_us);
CreatedSession FromProto(const v1::NodeSession& s);
void ToProto(const CreatedSession& c, bool with_key, v1::NodeSession* out);

}  // namespace vsurg::server::cluster
