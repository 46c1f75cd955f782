// Placement: a new session's node, and a draining node's live session moved to another.
#include "server/cluster/cluster_impl.h"

namespace vsurg::server::cluster {

Expected<std::optional<std::pair<db::NodeRecord, std::string>>> ClusterSessions::Impl::Reserve(
    const std::vector<db::NodeRecord>& nodes, const std::vector<std::string>& tried,
    size_t& with_room) {
  // Which nodes are up is this replica's view (its heartbeats), read before the store's lock.
  const int64_t now = db::NowUs();
  std::vector<const db::NodeRecord*> up;
  for (const db::NodeRecord& n : nodes)
    if (Healthy(n, now) && !n.draining) up.push_back(&n);
  const db::NodeRecord* best = nullptr;
  const auto choose = [&](const std::map<std::string, int>& load) -> std::optional<std::string> {
    best = nullptr;
    with_room = 0;
    double best_load = 0;
    for (const db::NodeRecord* n : up) {
      const auto it = load.find(n->name);
      const int sessions = it == load.end() ? 0 : it->second;
      if (sessions >= n->capacity) continue;
      ++with_room;
      if (std::find(tried.begin(), tried.end(), n->name) != tried.end()) continue;
      const double share = static_cast<double>(sessions) / n->capacity;
      if (!best || share < best_load ||
          (share == best_load &&
           (n->cpu < best->cpu || (n->cpu == best->cpu && n->name < best->name)))) {
        best = n;
        best_load = share;
      }
    }
    if (!best) return std::nullopt;
    return best->name;
  };
  // A reservation outlives the node call it is for (create_timeout_s) by a margin; one left by
  // a replica that died mid-placement counts no longer than that.
  const int64_t expires = now + static_cast<int64_t>((options.create_timeout_s + 10) * 1e6);
  auto reserved = store.ReservePlacement(expires, choose);
  if (!reserved.ok()) return reserved.error();
  if (!*reserved || !best) return std::optional<std::pair<db::NodeRecord, std::string>>();
  {
    std::lock_guard lock(placing_mutex);
    ++in_flight[best->name];
  }
  return std::make_optional(std::make_pair(*best, (*reserved)->token));
}

void ClusterSessions::Impl::Release(const std::string& node, const std::string& token) {
  {
    std::lock_guard lock(placing_mutex);
    if (--in_flight[node] == 0) in_flight.erase(node);
  }
  // A node that answered wrote its session's row in place of the reservation. One that refused
  // or did not answer leaves it: it goes before the next placement reads the load (a row the
  // node wrote after all stays, counted as the session it is).
  if (token.empty()) return;
  if (Status s = store.ReleasePlacement(token); !s.ok())
    Log("placement_release_failed", {{"node", node}, {"error", s.error().message}});
}

void ClusterSessions::Impl::Abandon(const db::NodeRecord& node, uint64_t id) {
  v1::NodeStopRequest req;
  req.set_id(id);
  req.set_reason("abandoned: its creator stopped waiting before the session was ready");
  req.set_abandoned(true);
  v1::NodeSession out;
  auto ctx = CallContext(options.token, options.call_timeout_s);
  const grpc::Status s = StubFor(node).Stop(ctx.get(), req, &out);
  Log("session_abandoned", {{"node", node.name},
                            {"session", static_cast<int64_t>(id)},
                            {"error", s.ok() ? std::string() : s.error_message()}});
}

grpc::Status ClusterSessions::Impl::Migrate(grpc::ServerContext* ctx, const v1::NodeHandoff* req,
                                            v1::NodeMoved* out) {
  if (grpc::Status s = Allowed(*ctx, req->from_node()); !s.ok()) return s;
  auto row = store.GetSession(static_cast<int64_t>(req->id()));
  if (!row.ok()) return ToGrpc(row.error());
  if (row->node != req->from_node() || !vsurg::IsLive(row->state))
    return grpc::Status(
        grpc::StatusCode::FAILED_PRECONDITION,
        "session " + std::to_string(req->id()) + " is not live on node " + req->from_node());
  std::vector<std::string> tried_nodes{req->from_node()};
  std::string tried;
  size_t with_room = 0;
  for (;;) {
    auto nodes = store.ListNodes();
    if (!nodes.ok()) return ToGrpc(nodes.error());
    auto reserved = Reserve(*nodes, tried_nodes, with_room);
    if (!reserved.ok()) return ToGrpc(reserved.error());
    if (!*reserved) break;
    const auto& [chosen, token] = **reserved;
    tried_nodes.push_back(chosen.name);
    v1::NodeHandoff handoff = *req;
    handoff.set_placement(token);
    v1::NodeSession reply;
    auto call = CallContext(options.token, options.create_timeout_s);
    const grpc::Status s = StubFor(chosen).Adopt(call.get(), handoff, &reply);
    Release(chosen.name, s.ok() ? "" : token);
    if (s.ok()) {
      Count(migrations, "moved");
      out->set_node(chosen.name);
      out->set_udp_host(reply.udp_host());
      out->set_udp_port(reply.udp_port());
      Log("session_migrated",
          {{"session", req->id()}, {"from", req->from_node()}, {"to", chosen.name}});
      return grpc::Status::OK;
    }
    Count(migrations, "refused");
    tried += (tried.empty() ? "" : "; ") + chosen.name + ": " + s.error_message();
    // The session or the sender is the reason (the session ended meanwhile, the sender lost
    // its lease): no other node would do better.
    if (s.error_code() == grpc::StatusCode::FAILED_PRECONDITION &&
        s.error_message().find("move refused") != std::string::npos)
      return s;
  }
  Count(migrations, "no_room");
  return grpc::Status(grpc::StatusCode::UNAVAILABLE, "no other simulation node takes session " +
                                                         std::to_string(req->id()) + " (" +
                                                         std::to_string(with_room) + " with room" +
                                                         (tried.empty() ? "" : ": " + tried) + ")");
}

Expected<CreatedSession> ClusterSessions::Create(const std::string& trainee,
                                                 const std::string& scene,
                                                 const scoring::TaskSettings& task) {
  Impl& d = *impl_;
  // The per-trainee limit over the whole site (each node also keeps its own).
  auto mine = d.store.ListSessions(trainee);
  if (!mine.ok()) return mine.error();
  const auto live = std::count_if(mine->begin(), mine->end(), [](const db::SessionRecord& r) {
    return vsurg::IsLive(r.state);
  });
  if (live >= d.options.max_sessions_per_user) {
    d.Count(d.refused, "trainee_limit");
    return Error{ErrorCode::kResourceExhausted,
                 "trainee '" + trainee + "' already has " + std::to_string(live) +
                     " live sessions (the limit is " +
                     std::to_string(d.options.max_sessions_per_user) + "); stop one first",
                 "trainee"};
  }
  std::vector<std::string> tried_nodes;
  std::string tried;
  size_t registered = 0, with_room = 0;
  for (;;) {
    auto nodes = d.store.ListNodes();
    if (!nodes.ok()) return nodes.error();
    registered = nodes->size();
    auto reserved = d.Reserve(*nodes, tried_nodes, with_room);
    if (!reserved.ok()) return reserved.error();
    if (!*reserved) break;
    const auto& [chosen, token] = **reserved;
    tried_nodes.push_back(chosen.name);
    v1::NodeCreateRequest req;
    req.set_trainee(trainee);
    req.set_scene(scene);
    convert::ToProto(task, req.mutable_task());
    req.set_placement(token);
    v1::NodeSession reply;
    auto ctx = CallContext(d.options.token, d.options.create_timeout_s);
    std::multimap<std::string, grpc::ClientContext*>::iterator waiting;
    {
      std::lock_guard lock(d.creating_mutex);
      waiting = d.creating.emplace(chosen.name, ctx.get());
    }
    const grpc::Status s = d.StubFor(chosen).Create(ctx.get(), req, &reply);
    {
      std::lock_guard lock(d.creating_mutex);
      d.creating.erase(waiting);
    }
    d.Release(chosen.name, s.ok() ? "" : token);
    if (s.ok()) {
      d.Count(d.placed, chosen.name);
      CreatedSession out = FromProto(reply);
      out.record.node = chosen.name;
      if (CallerDeadline::Passed()) {
        // The creator stopped waiting while the node built the scene (a station asks again
        // after its deadline): nobody will ever hold this key. Aborted now, not after the
        // not-started timeout, so it holds neither the trainee's slot nor the node's room while
        // the next Create is placed.
        d.Abandon(chosen, reply.session().id());
        d.Count(d.refused, "caller_gone");
        return Error{ErrorCode::kUnavailable,
                     "session " + std::to_string(reply.session().id()) +
                         " was ready after its creator stopped waiting; it is aborted",
                     ""};
      }
      return out;
    }
    const Error e = FromGrpc(s, "create on node " + chosen.name);
    // CANCELLED: the node was declared down while it built the scene (CancelCreatesOn).
    if (e.code != ErrorCode::kUnavailable && e.code != ErrorCode::kResourceExhausted &&
        s.error_code() != grpc::StatusCode::CANCELLED) {
      d.Count(d.refused, "invalid_request");
      return e;  // the request itself is wrong (a scene that does not exist, …)
    }
    d.Count(d.refused, "node_failed");
    tried += (tried.empty() ? "" : "; ") + e.message;
  }
  d.Count(d.refused, "no_room");
  return Error{ErrorCode::kUnavailable,
               "no simulation node has room for a new session (" + std::to_string(registered) +
                   " registered, " + std::to_string(with_room) + " with room" +
                   (tried.empty() ? "" : ": " + tried) + ")",
               ""};
}

}  // namespace vsurg::server::cluster
