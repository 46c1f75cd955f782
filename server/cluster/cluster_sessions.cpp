// The control role: the Sessions API over the site's nodes, its metrics, start and shutdown
// (placement: cluster_placement.cpp; the nodes' registry: cluster_registry.cpp; telemetry:
// cluster_telemetry.cpp).
#include <grpcpp/health_check_service_interface.h>

#include "common/core/realtime.h"
#include "server/cluster/cluster_impl.h"
#include "server/ops/metrics.h"

namespace vsurg::server::cluster {

v1::NodeService::Stub& ClusterSessions::Impl::StubFor(const db::NodeRecord& node) {
  std::lock_guard lock(stubs_mutex);
  auto& s = stubs[{node.name, node.grpc_address}];
  if (!s) s = v1::NodeService::NewStub(Channel(node.grpc_address, tls, node.name));
  return *s;
}

Expected<std::pair<db::SessionRecord, db::NodeRecord>> ClusterSessions::Impl::NodeOf(uint64_t id) {
  auto row = store.GetSession(static_cast<int64_t>(id));
  if (!row.ok()) return row.error();
  auto nodes = store.ListNodes();
  if (!nodes.ok()) return nodes.error();
  for (const db::NodeRecord& n : *nodes)
    if (n.name == row->node) {
      if (n.down)
        return Error{ErrorCode::kUnavailable,
                     "session " + std::to_string(id) + "'s node " + n.name + " is down", "id"};
      return std::make_pair(*row, n);
    }
  return Error{ErrorCode::kUnavailable,
               "session " + std::to_string(id) + " has no known node ('" + row->node + "')", "id"};
}

ClusterSessions::ClusterSessions(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ClusterSessions::~ClusterSessions() {
  Shutdown();
}
int ClusterSessions::port() const {
  return impl_->port;
}
int ClusterSessions::health_port() const {
  return impl_->health_port;
}

Expected<std::unique_ptr<ClusterSessions>> ClusterSessions::Start(db::Store& store,
                                                                  const ClusterOptions& options) {
  if (!ClusterOptions::kTelemetryHz.Contains(options.telemetry_hz))
    return InvalidArgument("telemetry-hz", ClusterOptions::kTelemetryHz.Must());
  auto tls = WatchTlsFiles(options);
  if (!tls.ok()) return tls.error();
  auto impl = std::make_unique<Impl>(store, options);
  impl->tls = std::move(tls).value();
  auto creds = ServerCredentials(options, impl->tls);
  if (!creds.ok()) return creds.error();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  builder.SetMaxReceiveMessageSize(kMaxInternalMessageBytes);
  builder.AddListeningPort(options.listen, *creds, &impl->port);
  builder.RegisterService(impl.get());
  impl->server = builder.BuildAndStart();
  if (!impl->server || impl->port == 0)
    return Error{ErrorCode::kUnavailable, "cannot listen on " + options.listen, "cluster-listen"};
  auto health = StartHealthServer(options, &impl->health_port);
  if (!health.ok()) return health.error();
  impl->health = std::move(health).value();
  Impl* p = impl.get();
  p->watchdog = std::thread([p] {
    NameThisThread("vsurg-watchdog");
    p->WatchdogLoop();
  });
  p->prober = std::thread([p] {
    NameThisThread("vsurg-prober");
    p->ProberLoop();
  });
  p->poller = std::thread([p] {
    NameThisThread("vsurg-poller");
    p->PollerLoop();
  });
  return std::unique_ptr<ClusterSessions>(new ClusterSessions(std::move(impl)));
}

Expected<db::SessionRecord> ClusterSessions::Start(uint64_t id) {
  return impl_->OnNode(
      id, "start", [&](v1::NodeService::Stub& s, grpc::ClientContext* ctx, v1::NodeSession* out) {
        v1::SessionRef req;
        req.set_id(id);
        return s.Start(ctx, req, out);
      });
}

Expected<db::SessionRecord> ClusterSessions::Stop(uint64_t id, const std::string& reason) {
  auto row = impl_->store.GetSession(static_cast<int64_t>(id));
  if (!row.ok()) return row.error();
  if (!vsurg::IsLive(row->state)) return row;  // ended already (or aborted with its node)
  return impl_->OnNode(
      id, "stop", [&](v1::NodeService::Stub& s, grpc::ClientContext* ctx, v1::NodeSession* out) {
        v1::NodeStopRequest req;
        req.set_id(id);
        req.set_reason(reason);
        return s.Stop(ctx, req, out);
      });
}

Expected<db::SessionRecord> ClusterSessions::Get(uint64_t id) {
  return impl_->store.GetSession(static_cast<int64_t>(id));
}

namespace {

// A station's credentials from the session's node (Join, JoinInstructor): the node's answer with
// its name, or its refusal named by `what`.
template <class Call>
Expected<CreatedSession> CredentialsOnNode(ClusterSessions::Impl& impl, uint64_t id,
                                           const std::string& what,
                                           std::unique_ptr<grpc::ClientContext> ctx, Call&& call) {
  auto at = impl.NodeOf(id);
  if (!at.ok()) return at.error();
  if (!vsurg::IsLive(at->first.state)) return ClusterSessions::Impl::NotLive(id);
  v1::NodeSession reply;
  const grpc::Status s = call(impl.StubFor(at->second), ctx.get(), &reply);
  if (!s.ok()) return FromGrpc(s, what + " on node " + at->second.name);
  CreatedSession out = FromProto(reply);
  out.record.node = at->second.name;
  return out;
}

}  // namespace

Expected<CreatedSession> ClusterSessions::Join(uint64_t id, bool with_surface) {
  v1::JoinRequest req;
  req.set_id(id);
  req.set_with_surface(with_surface);
  return CredentialsOnNode(
      *impl_, id, "join", impl_->ReadContext(),
      [&](auto& stub, auto* ctx, auto* out) { return stub.Join(ctx, req, out); });
}

namespace {

// A guidance call on the session's node: its answer, or the node's refusal named by `what`.
template <class Call>
Expected<SessionGuidance> GuidanceOnNode(ClusterSessions::Impl& impl, uint64_t id, const char* what,
                                         Call&& call) {
  auto at = impl.NodeOf(id);
  if (!at.ok()) return at.error();
  if (!vsurg::IsLive(at->first.state)) return ClusterSessions::Impl::NotLive(id);
  v1::Guidance reply;
  auto ctx = CallContext(impl.options.token, impl.options.call_timeout_s);
  const grpc::Status s = call(impl.StubFor(at->second), ctx.get(), &reply);
  if (!s.ok()) return FromGrpc(s, std::string(what) + " on node " + at->second.name);
  return grpcapi::FromProto(reply);
}

}  // namespace

// Four-handed training runs where the session runs: the control plane (which checked who may)
// asks the session's node, and the instructor's station is sent there, as the trainee's is.
Expected<CreatedSession> ClusterSessions::JoinInstructor(uint64_t id,
                                                         const std::string& instructor) {
  v1::NodeGuideRequest req;
  req.set_id(id);
  req.set_instructor(instructor);
  return CredentialsOnNode(
      *impl_, id, "instructor's join",
      CallContext(impl_->options.token, impl_->options.call_timeout_s),
      [&](auto& stub, auto* ctx, auto* out) { return stub.JoinInstructor(ctx, req, out); });
}

Status ClusterSessions::LeaveInstructor(uint64_t id, const std::string& instructor) {
  v1::NodeGuideRequest req;
  req.set_id(id);
  req.set_instructor(instructor);
  auto left = GuidanceOnNode(
      *impl_, id, "instructor's leave",
      [&](auto& stub, auto* ctx, auto* out) { return stub.LeaveInstructor(ctx, req, out); });
  return left.ok() ? Status::Ok() : Status(left.error());
}

Expected<SessionGuidance> ClusterSessions::Guide(uint64_t id, const std::string& instructor,
                                                 const sim::GuideRequest& request) {
  v1::NodeGuideRequest req;
  req.set_id(id);
  req.set_instructor(instructor);
  req.set_mode(grpcapi::GuideModeToProto(request.mode));
  req.set_alpha(request.alpha);
  return GuidanceOnNode(*impl_, id, "guide", [&](auto& stub, auto* ctx, auto* out) {
    return stub.Guide(ctx, req, out);
  });
}

Expected<SessionGuidance> ClusterSessions::Guidance(uint64_t id) const {
  v1::SessionRef req;
  req.set_id(id);
  return GuidanceOnNode(*impl_, id, "guidance", [&](auto& stub, auto* ctx, auto* out) {
    return stub.GetGuidance(ctx, req, out);
  });
}

Status ClusterSessions::RestSurface(uint64_t id, std::vector<geometry::Vec3>& positions,
                                    std::vector<int32_t>& triangles) const {
  auto at = impl_->NodeOf(id);
  if (!at.ok()) return at.error();
  v1::SessionRef req;
  req.set_id(id);
  v1::NodeSurface reply;
  auto ctx = impl_->ReadContext();
  const grpc::Status s = impl_->StubFor(at->second).RestSurface(ctx.get(), req, &reply);
  if (!s.ok()) return FromGrpc(s, "surface on node " + at->second.name);
  positions.clear();
  for (int i = 0; i + 2 < reply.positions_size(); i += 3)
    positions.push_back({reply.positions(i), reply.positions(i + 1), reply.positions(i + 2)});
  triangles.assign(reply.triangles().begin(), reply.triangles().end());
  return Status::Ok();
}

Expected<std::string> ClusterSessions::Trace(uint64_t id) const {
  auto at = impl_->NodeOf(id);
  if (!at.ok()) return at.error();
  v1::SessionRef req;
  req.set_id(id);
  v1::NodeTrace reply;
  auto ctx = impl_->ReadContext();
  const grpc::Status s = impl_->StubFor(at->second).Trace(ctx.get(), req, &reply);
  if (!s.ok()) return FromGrpc(s, "record on node " + at->second.name);
  return std::move(*reply.mutable_json());
}

bool ClusterSessions::IsLive(uint64_t id) const {
  auto row = impl_->store.GetSession(static_cast<int64_t>(id));
  return row.ok() && vsurg::IsLive(row->state);
}

int ClusterSessions::EndSessionsOf(const std::string& user, const std::string& reason) {
  auto nodes = impl_->store.ListNodes();
  if (!nodes.ok()) return 0;
  int ended = 0;
  const int64_t now = db::NowUs();
  for (const db::NodeRecord& n : *nodes) {
    if (!impl_->Healthy(n, now)) continue;
    v1::NodeUserRequest req;
    req.set_user(user);
    req.set_reason(reason);
    v1::NodeCount reply;
    auto ctx = CallContext(impl_->options.token, impl_->options.call_timeout_s);
    if (impl_->StubFor(n).EndSessionsOf(ctx.get(), req, &reply).ok()) ended += reply.count();
  }
  return ended;
}

void ClusterSessions::Collect(ops::MetricsText& m) const {
  const Impl& d = *impl_;
  {
    std::lock_guard lock(d.placing_mutex);
    m.Family("vsurg_placements_in_flight", "gauge",
             "Creates and moves this replica sent to a node and has no answer for yet, by node "
             "(the node builds their scenes, or does not answer).");
    for (const auto& [node, n] : d.in_flight)
      m.Sample("vsurg_placements_in_flight", {{"node", node}}, static_cast<double>(n));
  }
  {
    std::lock_guard lock(d.placements_mutex);
    m.Family("vsurg_placements_total", "counter", "Sessions this replica placed, by node.");
    for (const auto& [node, n] : d.placed)
      m.Sample("vsurg_placements_total", {{"node", node}}, static_cast<double>(n));
    m.Family("vsurg_placement_refusals_total", "counter",
             "Creates not placed by this replica (trainee_limit, no_room, invalid_request: a "
             "scene that does not exist, ...), node_failed: a chosen node's Create failed "
             "(another was tried), and caller_gone: the session was ready after its creator "
             "stopped waiting (aborted at once).");
    for (const char* reason :
         {"trainee_limit", "no_room", "invalid_request", "node_failed", "caller_gone"}) {
      const auto it = d.refused.find(reason);
      m.Sample("vsurg_placement_refusals_total", {{"reason", reason}},
               it == d.refused.end() ? 0.0 : static_cast<double>(it->second));
    }
    m.Family("vsurg_migrations_total", "counter",
             "Live sessions a draining node handed over through this replica, by outcome: moved "
             "(adopted by another node), refused (a node refused; another was tried), no_room.");
    for (const char* outcome : {"moved", "refused", "no_room"}) {
      const auto it = d.migrations.find(outcome);
      m.Sample("vsurg_migrations_total", {{"outcome", outcome}},
               it == d.migrations.end() ? 0.0 : static_cast<double>(it->second));
    }
  }
  m.Family("vsurg_telemetry_streams", "gauge",
           "Nodes this replica has a telemetry stream open to (only while someone watches).");
  m.Sample("vsurg_telemetry_streams", {}, d.streams_open.load(std::memory_order_relaxed));
  m.Family("vsurg_telemetry_streams_opened_total", "counter",
           "Telemetry streams opened (again when what is watched on a node changes).");
  m.Sample("vsurg_telemetry_streams_opened_total", {},
           static_cast<double>(d.watch_opened.load(std::memory_order_relaxed)));
  m.Family("vsurg_telemetry_received_bytes_total", "counter",
           "Telemetry received from the nodes (protobuf bytes).");
  m.Sample("vsurg_telemetry_received_bytes_total", {},
           static_cast<double>(d.watch_bytes.load(std::memory_order_relaxed)));
  auto nodes = d.store.ListNodes();
  if (!nodes.ok()) return;  // the store's own families say why
  auto rows = d.store.LiveSessionNodes();
  std::map<std::string, int> live;
  if (rows.ok())
    for (const auto& [node, id] : *rows) ++live[node];
  const int64_t now = db::NowUs();
  std::map<std::string, int> by_state{{"up", 0}, {"draining", 0}, {"down", 0}};
  for (const db::NodeRecord& n : *nodes)
    ++by_state[!d.Healthy(n, now) ? "down" : n.draining ? "draining" : "up"];
  m.Family("vsurg_nodes", "gauge", "Simulation nodes in the site's registry, by state.");
  for (const auto& [state, n] : by_state) m.Sample("vsurg_nodes", {{"state", state}}, n);
  m.Family("vsurg_node_live_sessions", "gauge", "Live sessions per node (the store's rows).");
  for (const db::NodeRecord& n : *nodes)
    if (!n.down) m.Sample("vsurg_node_live_sessions", {{"node", n.name}}, live[n.name]);
  m.Family("vsurg_node_capacity", "gauge", "Live sessions each node takes.");
  for (const db::NodeRecord& n : *nodes)
    if (!n.down) m.Sample("vsurg_node_capacity", {{"node", n.name}}, n.capacity);
  m.Family("vsurg_node_lease_age_seconds", "gauge",
           "Seconds since each up node's lease was last written to the store (it lapses past "
           "the store lease, --cluster-store-lease).");
  for (const db::NodeRecord& n : *nodes)
    if (!n.down)
      m.Sample("vsurg_node_lease_age_seconds", {{"node", n.name}},
               1e-6 * static_cast<double>(now - n.heartbeat_us));
  {
    std::lock_guard lock(d.heard_mutex);
    m.Family("vsurg_node_heartbeat_age_seconds", "gauge",
             "Seconds since this replica last heard each node that beats to it (down past the "
             "heartbeat timeout).");
    for (const auto& [name, h] : d.heard)
      m.Sample("vsurg_node_heartbeat_age_seconds", {{"node", name}},
               1e-6 * static_cast<double>(now - h.heard_us));
  }
  m.Family("vsurg_heartbeats_received_total", "counter",
           "Node heartbeats this replica answered or refused.");
  m.Sample("vsurg_heartbeats_received_total", {},
           static_cast<double>(d.beats_received.load(std::memory_order_relaxed)));
  m.Family("vsurg_heartbeat_store_writes_total", "counter",
           "Heartbeats and acquisitions this replica wrote to the store (the rest stayed in "
           "memory).");
  m.Sample("vsurg_heartbeat_store_writes_total", {},
           static_cast<double>(d.beats_written.load(std::memory_order_relaxed)));
  m.Family("vsurg_node_epoch", "gauge", "Each node's lease epoch.");
  for (const db::NodeRecord& n : *nodes)
    if (!n.down) m.Sample("vsurg_node_epoch", {{"node", n.name}}, static_cast<double>(n.epoch));
}

void ClusterSessions::Shutdown() {
  std::call_once(impl_->shutdown_once, [this] {
    {
      std::lock_guard lock(impl_->stop_mutex);
      impl_->stopping = true;
    }
    impl_->stop_cv.notify_all();
    if (impl_->watchdog.joinable()) impl_->watchdog.join();
    if (impl_->prober.joinable()) impl_->prober.join();
    if (impl_->poller.joinable()) impl_->poller.join();
    if (impl_->server) {
      impl_->server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
      impl_->server->Wait();
    }
    if (impl_->health) impl_->health->Shutdown();
  });
}

}  // namespace vsurg::server::cluster
