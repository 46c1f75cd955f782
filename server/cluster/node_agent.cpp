// The sim role: NodeService over this process's SessionManager, and the heartbeat thread.
#include <openssl/rand.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <grpcpp/health_check_service_interface.h>

#include "common/core/log.h"
#include "common/core/realtime.h"
#include "server/cluster/cluster_common.h"
#include "server/control/grpc_common.h"
#include "server/net/lease.h"
#include "server/ops/metrics.h"
#include "server/session/session_manager.h"

namespace vsurg::server::cluster {
namespace {

grpc::Status Unauthenticated() {
  return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "no valid cluster token");
}

double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void Log(const std::string& node, const std::string& event, LogFields fields = {}) {
  fields.insert(fields.begin(), {"node", node});
  LogEvent("vsurg-sim", event, fields);
}

// This process, among every process that ever ran under the node's name: 64 random bits.
std::string NewInstance() {
  std::array<unsigned char, 8> bytes{};
  if (RAND_bytes(bytes.data(), static_cast<int>(bytes.size())) != 1) {
    const auto t = std::chrono::steady_clock::now().time_since_epoch().count();
    std::memcpy(bytes.data(), &t, sizeof t);
  }
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (unsigned char b : bytes) out += kHex[b >> 4], out += kHex[b & 15];
  return out;
}

}  // namespace

struct NodeAgent::Impl final : public v1::NodeService::Service {
  SessionManager& sessions;
  NodeOptions options;
  TlsFiles tls;  // before the server and channels that use it
  std::unique_ptr<grpc::Server> server, health;
  int port = 0, health_port = 0;
  std::atomic<bool> draining{false};
  std::atomic<uint64_t> beats_answered{0}, beats_failed{0};  // heartbeats and acquisitions
  int64_t started_us = db::NowUs();

  // The latest telemetry of every live session, from the manager's sampler, with each session's
  // last surface state (the sampler sends one every third sample).
  std::mutex telemetry_mutex;
  std::map<uint64_t, SessionTelemetry> latest;
  uint64_t subscription = 0;

  std::mutex beat_mutex;
  std::condition_variable beat_cv;
  bool stopping = false, beat_now = false;
  std::thread heartbeat;
  std::once_flag shutdown_once;

  Lease& lease;
  const std::string instance = NewInstance();
  std::unique_ptr<v1::ClusterService::Stub> control;
  double beat_cpu = ProcessCpuSeconds();  // the CPU use since the last heartbeat
  std::chrono::steady_clock::time_point beat_time = std::chrono::steady_clock::now();

  Impl(SessionManager& s, const NodeOptions& o) : sessions(s), options(o), lease(*o.lease) {}

  v1::NodeHeartbeat Beat() {
    const double cpu1 = ProcessCpuSeconds();
    const auto t1 = std::chrono::steady_clock::now();
    const double wall = std::chrono::duration<double>(t1 - beat_time).count();
    v1::NodeHeartbeat beat;
    beat.set_name(options.name);
    beat.set_grpc_address(options.advertise);
    beat.set_udp_host(options.udp_host);
    beat.set_udp_port(static_cast<uint32_t>(options.udp_port));
    beat.set_capacity(options.capacity);
    beat.set_sessions(sessions.LiveCount());
    beat.set_cpu(wall > 0 ? (cpu1 - beat_cpu) / wall : 0);
    beat.set_draining(draining.load());
    beat.set_started_us(started_us);
    beat.set_instance(instance);
    beat.set_epoch(lease.epoch());
    beat_cpu = cpu1;
    beat_time = t1;
    return beat;
  }

  // The lease's end for an answer to a request sent at `sent` (server/net/lease.h).
  Lease::Clock::time_point Until(Lease::Clock::time_point sent, double lease_s) const {
    const double s = std::max(0.0, lease_s - options.cluster.lease_margin_s);
    return sent +
           std::chrono::duration_cast<Lease::Clock::duration>(std::chrono::duration<double>(s));
  }

  // One attempt to take the node's name. OK: the lease is held (a new epoch).
  grpc::Status Acquire() {
    v1::NodeHeartbeat beat = Beat();
    beat.set_epoch(0);
    v1::NodeLeaseReply reply;
    const auto sent = Lease::Clock::now();
    // Longer than a heartbeat's deadline: an acquisition is a transaction that may wait on the
    // name's row, and a node without a lease has nothing to renew meanwhile.
    auto ctx = CallContext(options.cluster.token, std::min(options.cluster.call_timeout_s,
                                                           options.cluster.heartbeat_timeout_s));
    const grpc::Status s = control->Acquire(ctx.get(), beat, &reply);
    if (!s.ok()) return s;
    lease.Grant(reply.epoch(), Until(sent, reply.lease_s()));
    Log(options.name, "lease_acquired",
        {{"epoch", reply.epoch()}, {"instance", instance}, {"leftovers_aborted", reply.aborted()}});
    return s;
  }

  // The site no longer counts on this node's sessions: drop them, write nothing.
  void LeaseLost(const std::string& why) {
    const int64_t epoch = lease.epoch();
    lease.Revoke();
    const int dropped = sessions.AbandonAll("node " + options.name + " lost its lease: " + why);
    Log(options.name, "lease_lost",
        {{"epoch", epoch}, {"sessions_dropped", dropped}, {"error", why}});
  }

  void OnTelemetry(const std::vector<SessionTelemetry>& list) {
    std::lock_guard lock(telemetry_mutex);
    std::map<uint64_t, SessionTelemetry> next;
    for (const SessionTelemetry& t : list) {
      SessionTelemetry& n = next[t.id] = t;
      const auto old = latest.find(t.id);
      if (!t.has_surface && old != latest.end() && old->second.has_surface) {
        n.has_surface = true;
        n.surface_frame = old->second.surface_frame;
        n.surface_indices = std::move(old->second.surface_indices);
        n.surface_positions = std::move(old->second.surface_positions);
      }
    }
    latest = std::move(next);
  }

  Lease::Clock::duration Period() const {
    return std::chrono::duration_cast<Lease::Clock::duration>(
        std::chrono::duration<double>(options.cluster.heartbeat_period_s));
  }

  // Renews the lease every period; without one (lost, or never taken because the control plane
  // was unreachable at start) acquires the name again.
  void HeartbeatLoop() {
    Lease::Clock::time_point next_beat = Lease::Clock::now();
    bool reachable = true;
    std::unique_lock lock(beat_mutex);
    while (!stopping) {
      lock.unlock();
      grpc::Status s;
      if (!lease.held()) {
        s = Acquire();
        if (s.error_code() == grpc::StatusCode::ALREADY_EXISTS)
          Log(options.name, "lease_refused", {{"error", s.error_message()}});
      } else {
        v1::HeartbeatReply reply;
        const auto sent = Lease::Clock::now();
        // An answer is worth having up to half the lease after it was asked for (it extends the
        // lease from when it was sent): a loaded control plane that answers in 0.8 s keeps the
        // node serving. The next heartbeat goes a period after this one was sent.
        next_beat = sent + Period();
        auto ctx = CallContext(
            options.cluster.token,
            std::max(options.cluster.heartbeat_period_s, options.cluster.heartbeat_timeout_s / 2));
        s = control->Heartbeat(ctx.get(), Beat(), &reply);
        if (s.ok()) {
          lease.Extend(Until(sent, reply.lease_s()));
        } else if (s.error_code() == grpc::StatusCode::FAILED_PRECONDITION) {
          LeaseLost(s.error_message());
          lock.lock();
          continue;  // acquire again at once
        }
      }
      (s.ok() ? beats_answered : beats_failed).fetch_add(1, std::memory_order_relaxed);
      const bool ok = s.ok() || s.error_code() == grpc::StatusCode::ALREADY_EXISTS;
      if (ok != reachable) {
        reachable = ok;
        Log(options.name, reachable ? "control_reachable" : "control_unreachable",
            reachable ? LogFields{} : LogFields{{"error", s.error_message()}});
      }
      lock.lock();
      if (!s.ok() || !lease.held()) next_beat = Lease::Clock::now() + Period();
      beat_cv.wait_until(lock, next_beat, [&] { return stopping || beat_now; });
      beat_now = false;
    }
  }

  // Live migration: each live session handed to another node through the control plane, one
  // at a time (each is out of service only for its own move). One that no node takes serves on
  // here; `attempts` counts each session's tries over the rounds (at most kMoveAttempts). Returns
  // how many moved.
  static constexpr int kMoveAttempts = 5;
  int MigrateAll(std::map<uint64_t, int>& attempts) {
    int moved = 0, kept = 0;
    for (uint64_t id : sessions.LiveIds()) {
      // Without a valid lease the site may be re-placing this node's sessions: hand nothing over
      // (the next round, once the lease is back, will).
      if (!lease.Valid()) break;
      if (attempts[id]++ >= kMoveAttempts) continue;
      const auto t0 = std::chrono::steady_clock::now();
      auto handoff = sessions.BeginMove(id);
      if (!handoff.ok()) continue;  // ended meanwhile
      v1::NodeHandoff req;
      req.set_from_node(options.name);
      req.set_id(id);
      req.set_state(handoff->Bytes());
      v1::NodeMoved reply;
      // Longer than the control plane's own deadline for the adoption (create_timeout_s), after
      // which the adopting node commits nothing: an answer that does not come in this time is a
      // move that did not happen, unless the store says otherwise (CancelMove reads it).
      auto ctx = CallContext(options.cluster.token,
                             2 * options.cluster.create_timeout_s + options.cluster.call_timeout_s);
      const grpc::Status s = control->Migrate(ctx.get(), req, &reply);
      const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::steady_clock::now() - t0)
                          .count();
      if (s.ok()) {
        sessions.FinishMove(id);
        ++moved;
        Log(options.name, "session_migrated",
            {{"session", id}, {"to", reply.node()}, {"bytes", req.state().size()}, {"ms", ms}});
      } else {
        sessions.CancelMove(id);  // serves here again, unless the store says it moved
        ++kept;
        Log(options.name, "session_migration_failed",
            {{"session", id}, {"error", s.error_message()}, {"ms", ms}});
      }
    }
    if (moved + kept > 0) Log(options.name, "migrated", {{"moved", moved}, {"kept", kept}});
    return moved;
  }

  // --- NodeService ---
  // Only the control plane calls a node: the site's token, and with TLS a control replica's
  // certificate (a node's own, or another node's, is refused).
  grpc::Status Allowed(const grpc::ServerContext& ctx) const {
    if (!Authorized(ctx, options.cluster.token)) return Unauthenticated();
    return CheckPeer(ctx, options.cluster, options.cluster.control_name,
                     "a control replica (" + options.cluster.control_name + ")");
  }
  grpc::Status Create(grpc::ServerContext* ctx, const v1::NodeCreateRequest* req,
                      v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    if (draining)
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "node " + options.name + " is draining: no new sessions");
    if (!lease.Valid())
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "node " + options.name + " holds no lease now: no new sessions");
    const auto t0 = std::chrono::steady_clock::now();
    auto c = sessions.Create(req->trainee(), req->scene(), convert::FromProto(req->task()),
                             req->placement());
    if (!c.ok()) return grpcapi::ToGrpcStatus(c.error());
    Log(options.name, "create_answered",
        {{"session", c->record.id},
         {"scene", req->scene()},
         {"ms", std::chrono::duration_cast<std::chrono::milliseconds>(
                    std::chrono::steady_clock::now() - t0)
                    .count()}});
    ToProto(*c, true, out);
    return grpc::Status::OK;
  }
  grpc::Status Start(grpc::ServerContext* ctx, const v1::SessionRef* req,
                     v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    auto r = sessions.Start(req->id());
    if (!r.ok()) return grpcapi::ToGrpcStatus(r.error());
    grpcapi::ToProto(*r, out->mutable_session());
    return grpc::Status::OK;
  }
  grpc::Status Stop(grpc::ServerContext* ctx, const v1::NodeStopRequest* req,
                    v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    auto r = req->abandoned() ? sessions.Abandon(req->id(), req->reason())
                              : sessions.Stop(req->id(), req->reason());
    if (!r.ok()) return grpcapi::ToGrpcStatus(r.error());
    grpcapi::ToProto(*r, out->mutable_session());
    return grpc::Status::OK;
  }
  grpc::Status Join(grpc::ServerContext* ctx, const v1::JoinRequest* req,
                    v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    auto c = sessions.Join(req->id(), req->with_surface());
    if (!c.ok()) return grpcapi::ToGrpcStatus(c.error());
    if (!req->with_surface()) c->surface.reset(), c->needle.reset();
    ToProto(*c, true, out);
    return grpc::Status::OK;
  }
  // Four-handed training where the session runs; the control plane decided who may.
  grpc::Status JoinInstructor(grpc::ServerContext* ctx, const v1::NodeGuideRequest* req,
                              v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    auto c = sessions.JoinInstructor(req->id(), req->instructor());
    if (!c.ok()) return grpcapi::ToGrpcStatus(c.error());
    ToProto(*c, true, out);
    return grpc::Status::OK;
  }
  grpc::Status LeaveInstructor(grpc::ServerContext* ctx, const v1::NodeGuideRequest* req,
                               v1::Guidance*) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    if (Status s = sessions.LeaveInstructor(req->id(), req->instructor()); !s.ok())
      return grpcapi::ToGrpcStatus(s.error());
    return grpc::Status::OK;
  }
  grpc::Status Guide(grpc::ServerContext* ctx, const v1::NodeGuideRequest* req,
                     v1::Guidance* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    return AnswerGuidance(sessions.Guide(req->id(), req->instructor(),
                                         {grpcapi::GuideModeFromProto(req->mode()), req->alpha()}),
                          out);
  }
  grpc::Status GetGuidance(grpc::ServerContext* ctx, const v1::SessionRef* req,
                           v1::Guidance* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    return AnswerGuidance(sessions.Guidance(req->id()), out);
  }
  static grpc::Status AnswerGuidance(const Expected<SessionGuidance>& g, v1::Guidance* out) {
    if (!g.ok()) return grpcapi::ToGrpcStatus(g.error());
    grpcapi::ToProto(*g, out);
    return grpc::Status::OK;
  }
  grpc::Status RestSurface(grpc::ServerContext* ctx, const v1::SessionRef* req,
                           v1::NodeSurface* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    std::vector<geometry::Vec3> positions;
    std::vector<int32_t> triangles;
    if (Status s = sessions.RestSurface(req->id(), positions, triangles); !s.ok())
      return grpcapi::ToGrpcStatus(s.error());
    out->mutable_positions()->Reserve(static_cast<int>(3 * positions.size()));
    for (const auto& p : positions)
      for (int k = 0; k < 3; ++k) out->add_positions(static_cast<float>(p[k]));
    out->mutable_triangles()->Assign(triangles.begin(), triangles.end());
    return grpc::Status::OK;
  }
  grpc::Status Trace(grpc::ServerContext* ctx, const v1::SessionRef* req,
                     v1::NodeTrace* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    auto trace = sessions.Trace(req->id());
    if (!trace.ok()) return grpcapi::ToGrpcStatus(trace.error());
    out->set_json(std::move(trace).value());
    return grpc::Status::OK;
  }
  grpc::Status Adopt(grpc::ServerContext* ctx, const v1::NodeHandoff* req,
                     v1::NodeSession* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    if (draining)
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "node " + options.name + " is draining: no new sessions");
    auto handoff = SessionHandoff::FromBytes(req->state());
    if (!handoff.ok()) return grpcapi::ToGrpcStatus(handoff.error());
    if (handoff->id != static_cast<int64_t>(req->id()) || handoff->from_node != req->from_node())
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "the handoff is of another session or node than the request names");
    const auto t0 = std::chrono::steady_clock::now();
    // Committed only before the control plane's deadline: past it, the sender (which waits
    // longer) may already have taken the session back.
    auto c = sessions.Adopt(*handoff, ctx->deadline(), req->placement());
    if (!c.ok()) return grpcapi::ToGrpcStatus(c.error());
    Log(options.name, "session_adopted",
        {{"session", c->record.id},
         {"from", req->from_node()},
         {"ms", std::chrono::duration_cast<std::chrono::milliseconds>(
                    std::chrono::steady_clock::now() - t0)
                    .count()}});
    c->surface.reset(), c->needle.reset();  // the station has them from its join
    ToProto(*c, true, out);
    return grpc::Status::OK;
  }
  grpc::Status EndSessionsOf(grpc::ServerContext* ctx, const v1::NodeUserRequest* req,
                             v1::NodeCount* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    out->set_count(sessions.EndSessionsOf(req->user(), req->reason()));
    return grpc::Status::OK;
  }
  grpc::Status Telemetry(grpc::ServerContext* ctx, const v1::NodeTelemetryRequest*,
                         v1::NodeTelemetry* out) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    std::lock_guard lock(telemetry_mutex);
    for (const auto& [id, t] : latest) convert::ToProto(t, out->add_sessions());
    return grpc::Status::OK;
  }

  // One control replica's watch: the figures it asked for at its rate, a surface only to a
  // replica showing that session and only once per new frame. A message with nothing changed is
  // still sent (the figures are the latest; a quiet session is still live).
  grpc::Status Watch(grpc::ServerContext* ctx, const v1::NodeWatchRequest* req,
                     grpc::ServerWriter<v1::NodeTelemetry>* writer) override {
    if (grpc::Status s = Allowed(*ctx); !s.ok()) return s;
    if (!(req->rate_hz() >= 1 && req->rate_hz() <= 120))
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "rate_hz must be within 1..120");
    const std::set<uint64_t> wanted(req->sessions().begin(), req->sessions().end());
    // Session → the frame this stream last sent; none yet, so the first goes whatever its frame
    // (a viewer starts from the session's state, at rest or not).
    std::map<uint64_t, uint64_t> surface_sent;
    for (uint64_t id : req->surfaces()) surface_sent[id] = ~uint64_t{0};
    const auto period = std::chrono::microseconds(static_cast<int64_t>(1e6 / req->rate_hz()));
    auto next = std::chrono::steady_clock::now();
    for (;;) {
      v1::NodeTelemetry out;
      {
        std::lock_guard lock(telemetry_mutex);
        for (const auto& [id, t] : latest) {
          if (!req->all() && !wanted.count(id)) continue;
          auto sent = surface_sent.find(id);
          const bool surface =
              sent != surface_sent.end() && t.has_surface && t.surface_frame != sent->second;
          if (surface) sent->second = t.surface_frame;
          convert::ToProto(t, out.add_sessions(), surface);
        }
      }
      if (!writer->Write(out)) return grpc::Status::OK;  // the replica went away
      next += period;
      std::unique_lock lock(beat_mutex);
      if (beat_cv.wait_until(lock, next, [&] { return stopping; }) || ctx->IsCancelled())
        return grpc::Status::OK;
    }
  }
};

NodeAgent::NodeAgent(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NodeAgent::~NodeAgent() {
  Shutdown();
}
int NodeAgent::port() const {
  return impl_->port;
}
int NodeAgent::health_port() const {
  return impl_->health_port;
}

Expected<std::unique_ptr<NodeAgent>> NodeAgent::Start(SessionManager& sessions,
                                                      const NodeOptions& options) {
  if (options.name.empty() || options.name.size() > 64)
    return InvalidArgument("node-name", "a node name of 1 to 64 characters is required");
  if (options.control.empty())
    return InvalidArgument("control", "the control plane's internal address is required");
  if (!NodeOptions::kCapacity.Contains(options.capacity))
    return InvalidArgument("capacity", NodeOptions::kCapacity.Must() + " sessions");
  if (!options.lease) return InvalidArgument("lease", "a node needs a lease to hold");
  const ClusterOptions& c = options.cluster;
  if (!(c.lease_margin_s >= 0 &&
        c.heartbeat_timeout_s - c.lease_margin_s >= 2 * c.heartbeat_period_s))
    return InvalidArgument("lease-margin",
                           "the lease (heartbeat timeout less the margin) must last at least two "
                           "heartbeat periods");
  auto tls = WatchTlsFiles(options.cluster);
  if (!tls.ok()) return tls.error();
  auto impl = std::make_unique<Impl>(sessions, options);
  impl->tls = std::move(tls).value();
  auto creds = ServerCredentials(options.cluster, impl->tls);
  if (!creds.ok()) return creds.error();
  grpc::EnableDefaultHealthCheckService(true);  // readiness (deploy/k8s/sim.yaml)
  grpc::ServerBuilder builder;
  builder.SetMaxReceiveMessageSize(kMaxInternalMessageBytes);
  builder.AddListeningPort(options.cluster.listen, *creds, &impl->port);
  builder.RegisterService(impl.get());
  impl->server = builder.BuildAndStart();
  if (!impl->server || impl->port == 0)
    return Error{ErrorCode::kUnavailable, "cannot listen on " + options.cluster.listen,
                 "cluster-listen"};
  auto health = StartHealthServer(options.cluster, &impl->health_port);
  if (!health.ok()) {
    impl->server->Shutdown();
    return health.error();
  }
  impl->health = std::move(health).value();
  if (impl->options.advertise.empty()) {
    const std::string& l = options.cluster.listen;
    impl->options.advertise = l.substr(0, l.rfind(':') + 1) + std::to_string(impl->port);
  }
  Impl* p = impl.get();
  // The name first. Held by another live process: it may be one that has just died (its lease
  // runs out within the heartbeat timeout), so ask until then, and refuse to start if it is
  // still held. A control plane that does not answer (or answers too slowly, on a loaded
  // machine) is asked again within the same window; one that never answers in it does not stop
  // the start: the heartbeat thread keeps asking, and the node serves nothing until it holds the
  // lease.
  p->control =
      v1::ClusterService::NewStub(Channel(options.control, p->tls, options.cluster.control_name));
  const auto give_up = std::chrono::steady_clock::now() +
                       std::chrono::microseconds(static_cast<int64_t>(
                           (c.heartbeat_timeout_s + 2 * c.heartbeat_period_s) * 1e6));
  bool held_elsewhere = false;
  std::string last_error;
  for (;;) {
    const grpc::Status s = p->Acquire();
    if (s.ok()) break;
    if (s.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
        s.error_code() == grpc::StatusCode::PERMISSION_DENIED ||
        s.error_code() == grpc::StatusCode::INVALID_ARGUMENT) {
      p->server->Shutdown();
      Error e = FromGrpc(s, "acquire the node name " + options.name);
      if (s.error_code() == grpc::StatusCode::PERMISSION_DENIED) e.field = "node-name";
      return e;
    }
    // A refusal is the last word until the control plane answers otherwise.
    if (s.error_code() == grpc::StatusCode::ALREADY_EXISTS) held_elsewhere = true;
    if (s.error_code() == grpc::StatusCode::ALREADY_EXISTS || !held_elsewhere)
      last_error = s.error_message();
    if (std::chrono::steady_clock::now() >= give_up) {
      if (held_elsewhere) {
        p->server->Shutdown();
        return Error{ErrorCode::kAlreadyExists, last_error, "node-name"};
      }
      Log(options.name, "control_unreachable", {{"error", last_error}});
      break;
    }
    std::this_thread::sleep_for(
        std::chrono::microseconds(static_cast<int64_t>(c.heartbeat_period_s * 1e6)));
  }
  p->subscription = sessions.Subscribe(
      0, [p](const std::vector<SessionTelemetry>& list, bool) { p->OnTelemetry(list); });
  p->heartbeat = std::thread([p] {
    NameThisThread("vsurg-heartbeat");
    p->HeartbeatLoop();
  });
  Log(options.name, "node_started",
      {{"internal", p->options.advertise},
       {"udp", options.udp_host + ":" + std::to_string(options.udp_port)},
       {"capacity", options.capacity},
       {"capacity_from", options.capacity_from}});
  return std::unique_ptr<NodeAgent>(new NodeAgent(std::move(impl)));
}

void NodeAgent::Collect(ops::MetricsText& m) const {
  const Lease& lease = impl_->lease;
  m.Family("vsurg_lease_held", "gauge", "1 while this node holds its name's lease (valid or not).");
  m.Sample("vsurg_lease_held", {}, lease.held() ? 1 : 0);
  m.Family("vsurg_lease_epoch", "gauge", "The epoch of the lease held (0: none).");
  m.Sample("vsurg_lease_epoch", {}, static_cast<double>(lease.epoch()));
  m.Family("vsurg_lease_seconds_left", "gauge",
           "Seconds of validity left on the node's own clock (negative: lapsed, no forces).");
  m.Sample("vsurg_lease_seconds_left", {}, lease.held() ? lease.SecondsLeft() : 0);
  m.Family("vsurg_node_draining", "gauge", "1 while the node drains (no new sessions).");
  m.Sample("vsurg_node_draining", {}, impl_->draining ? 1 : 0);
  m.Family("vsurg_heartbeats_total", "counter",
           "Heartbeats and acquisitions sent to the control plane, by outcome.");
  m.Sample("vsurg_heartbeats_total", {{"outcome", "answered"}},
           static_cast<double>(impl_->beats_answered.load(std::memory_order_relaxed)));
  m.Sample("vsurg_heartbeats_total", {{"outcome", "failed"}},
           static_cast<double>(impl_->beats_failed.load(std::memory_order_relaxed)));
}

int NodeAgent::Drain(double timeout_s) {
  impl_->draining = true;
  {
    std::lock_guard lock(impl_->beat_mutex);
    impl_->beat_now = true;  // tell the control plane now, not at the next period
  }
  impl_->beat_cv.notify_all();
  Log(impl_->options.name, "draining",
      {{"live", impl_->sessions.LiveCount()}, {"timeout_s", timeout_s}});
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6));
  // Rounds of moves, a second apart, while sessions are left: a node without its lease for a
  // moment (a control plane too loaded to answer a heartbeat) moves nothing until it has it
  // again, and a session no node took (no room yet) is offered again, a few times.
  int moved = 0;
  auto next_round = std::chrono::steady_clock::now();
  std::map<uint64_t, int> attempts;
  while (impl_->sessions.LiveCount() > 0 && std::chrono::steady_clock::now() < deadline) {
    if (impl_->options.migrate_on_drain && std::chrono::steady_clock::now() >= next_round) {
      moved += impl_->MigrateAll(attempts);
      next_round = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  Log(impl_->options.name, "drained", {{"live", impl_->sessions.LiveCount()}, {"moved", moved}});
  return moved;
}

void NodeAgent::Shutdown() {
  std::call_once(impl_->shutdown_once, [this] {
    {
      std::lock_guard lock(impl_->beat_mutex);
      impl_->stopping = true;
    }
    impl_->beat_cv.notify_all();
    if (impl_->heartbeat.joinable()) impl_->heartbeat.join();
    impl_->sessions.Unsubscribe(impl_->subscription);
    if (impl_->server) {
      impl_->server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
      impl_->server->Wait();
    }
    if (impl_->health) impl_->health->Shutdown();
  });
}

}  // namespace vsurg::server::cluster
