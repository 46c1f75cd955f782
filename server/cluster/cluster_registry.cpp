// The nodes' registry: their leases (Acquire), heartbeats kept in memory, the watchdog that
// declares a silent node down and the prober that finds a gone one sooner.
#include "server/cluster/cluster_impl.h"

namespace vsurg::server::cluster {

bool ClusterSessions::Impl::Healthy(const db::NodeRecord& n, int64_t now) const {
  if (n.down) return false;
  std::lock_guard lock(heard_mutex);
  const auto it = heard.find(n.name);
  if (it != heard.end() && it->second.instance == n.instance && it->second.epoch == n.epoch)
    return now - it->second.heard_us <= TimeoutUs();
  return now - n.heartbeat_us <= StoreLeaseUs();
}

grpc::Status ClusterSessions::Impl::ToGrpc(const Error& e) {
  grpc::StatusCode code = grpc::StatusCode::UNAVAILABLE;
  if (e.code == ErrorCode::kInvalidArgument) code = grpc::StatusCode::INVALID_ARGUMENT;
  if (e.code == ErrorCode::kAlreadyExists) code = grpc::StatusCode::ALREADY_EXISTS;
  if (e.code == ErrorCode::kFailedPrecondition) code = grpc::StatusCode::FAILED_PRECONDITION;
  return grpc::Status(code, e.message);
}

grpc::Status ClusterSessions::Impl::Allowed(const grpc::ServerContext& ctx,
                                            const std::string& node) const {
  if (!Authorized(ctx, options.token))
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "no valid cluster token");
  grpc::Status s = CheckPeer(ctx, options, node, "node " + node);
  if (s.ok() && options.tls() && node == options.control_name)  // a control replica's cert
    s = grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                     "'" + node + "' is the control replicas' name, not a node's");
  if (!s.ok()) Log("node_refused", {{"node", node}, {"error", s.error_message()}});
  return s;
}

grpc::Status ClusterSessions::Impl::Acquire(grpc::ServerContext* ctx, const v1::NodeHeartbeat* req,
                                            v1::NodeLeaseReply* out) {
  if (grpc::Status s = Allowed(*ctx, req->name()); !s.ok()) return s;
  const db::NodeRecord n = FromProto(*req, db::NowUs());
  auto lease = store.AcquireNode(
      n, StoreLeaseUs(), "simulation node " + n.name + " restarted (its name was taken again)");
  if (!lease.ok()) return ToGrpc(lease.error());
  {
    std::lock_guard lock(heard_mutex);
    Heard& h = heard[n.name];
    h = {n.instance, lease->epoch, n.heartbeat_us, n.heartbeat_us, n, false, false};
    h.last.epoch = lease->epoch;
  }
  beats_written.fetch_add(1, std::memory_order_relaxed);
  out->set_epoch(lease->epoch);
  out->set_lease_s(options.heartbeat_timeout_s);
  out->set_aborted(lease->aborted);
  Log("node_acquired", {{"node", n.name},
                        {"epoch", lease->epoch},
                        {"instance", n.instance},
                        {"address", n.grpc_address},
                        {"leftovers_aborted", lease->aborted}});
  return grpc::Status::OK;
}

grpc::Status ClusterSessions::Impl::Heartbeat(grpc::ServerContext* ctx,
                                              const v1::NodeHeartbeat* req,
                                              v1::HeartbeatReply* out) {
  if (grpc::Status s = Allowed(*ctx, req->name()); !s.ok()) return s;
  const int64_t now = db::NowUs();
  const db::NodeRecord n = FromProto(*req, now);
  beats_received.fetch_add(1, std::memory_order_relaxed);
  out->set_lease_s(options.heartbeat_timeout_s);
  {
    std::lock_guard lock(heard_mutex);
    const auto it = heard.find(n.name);
    if (it != heard.end() && it->second.instance == n.instance && it->second.epoch == n.epoch) {
      Heard& h = it->second;
      // Heard, whatever the store says of it next: a slow write below never looks like silence.
      h.heard_us = std::max(h.heard_us, now);
      // Safe to answer from memory: the lease this answer grants (at most a timeout from now)
      // ends before the row's, with a period to spare.
      const bool safe = h.written_us + StoreLeaseUs() >= now + TimeoutUs() + PeriodUs();
      const bool due = h.written_us + StoreLeaseUs() < now + RenewAheadUs();
      if (!h.condemned && !PlacementFactsChanged(h.last, n) && safe) {
        if (!due || h.renewing) {  // a renewal in flight does not hold the others up
          h.last = n;
          return grpc::Status::OK;
        }
        h.renewing = true;  // this heartbeat renews the row; the next wait for none
      }
    }
  }
  // Conditional on the lease (instance, epoch, not down): a node the site gave up on is
  // refused here, whichever replica gave up on it.
  const Status written = store.BeatNode(n);
  const int64_t took_ms = (db::NowUs() - now) / 1000;
  if (!written.ok() || took_ms >= 1000)  // an operator's first clue to a slow or failing store
    Log("lease_write", {{"node", n.name},
                        {"ms", took_ms},
                        {"error", written.ok() ? "" : written.error().message}});
  std::lock_guard lock(heard_mutex);
  if (!written.ok()) {
    const auto it = heard.find(n.name);
    if (it != heard.end()) it->second.renewing = false;
    if (written.error().code == ErrorCode::kFailedPrecondition) heard.erase(n.name);
    return ToGrpc(written.error());
  }
  beats_written.fetch_add(1, std::memory_order_relaxed);
  const auto it = heard.find(n.name);
  if (it != heard.end() && it->second.instance == n.instance && it->second.epoch == n.epoch) {
    // Later heartbeats may have been answered meanwhile; a decision to declare the node down
    // taken meanwhile stands (the store orders it against this write).
    Heard& h = it->second;
    h.heard_us = std::max(h.heard_us, now);
    h.written_us = std::max(h.written_us, now);
    h.last = n;
    h.renewing = false;
  } else {
    heard[n.name] = {n.instance, n.epoch, now, now, n, false, false};
  }
  return grpc::Status::OK;
}

void ClusterSessions::Impl::DeclareDown(const db::NodeRecord& n, int64_t now,
                                        const std::string& reason, LogFields fields) {
  {
    std::lock_guard lock(heard_mutex);
    const auto it = heard.find(n.name);
    if (it != heard.end()) it->second.condemned = true;
  }
  auto aborted = store.MarkNodeDown(n.name, n.heartbeat_us + 1, now, reason);
  {
    std::lock_guard lock(heard_mutex);
    const auto it = heard.find(n.name);
    // Down: its next heartbeat meets the store's refusal. Not down: a heartbeat was written
    // since (here, which replaced this entry, or at another replica, which hears it now).
    if (it != heard.end() && it->second.condemned) heard.erase(it);
  }
  if (!aborted.ok() || !aborted->has_value()) return;
  fields.insert(fields.begin(), {"sessions_aborted", **aborted});
  fields.insert(fields.begin(), {"node", n.name});
  fields.push_back({"silent_ms", (now - n.heartbeat_us) / 1000});
  Log("node_down", fields);
  CancelCreatesOn(n.name);
}

void ClusterSessions::Impl::WatchdogLoop() {
  // A fifth of the heartbeat period: a silent node is found within 2.1 s, not 2.5 s.
  while (WaitFor(options.heartbeat_period_s / 5)) {
    auto nodes = store.ListNodes();
    if (!nodes.ok()) continue;
    const int64_t now = db::NowUs();
    std::vector<db::NodeRecord> late, silent, lapsed;
    {
      std::lock_guard lock(heard_mutex);
      std::map<std::string, const db::NodeRecord*> rows;
      for (const db::NodeRecord& n : *nodes) rows[n.name] = &n;
      for (auto it = heard.begin(); it != heard.end();) {
        const auto row = rows.find(it->first);
        // The store knows better (down, a newer holder, or another replica hears the node
        // now): the next heartbeat here asks it.
        if (row == rows.end() || row->second->down ||
            row->second->instance != it->second.instance ||
            row->second->epoch != it->second.epoch ||
            row->second->heartbeat_us > it->second.heard_us) {
          if (!it->second.condemned) {
            it = heard.erase(it);
            continue;
          }
        } else if (!it->second.condemned) {
          db::NodeRecord n = *row->second;
          n.heartbeat_us = it->second.heard_us;
          const int64_t quiet = now - n.heartbeat_us;
          if (quiet > TimeoutUs())
            silent.push_back(n);
          else if (quiet > LateUs())
            late.push_back(n);
        }
        ++it;
      }
      for (const db::NodeRecord& n : *nodes)
        if (!n.down && !heard.count(n.name) && now - n.heartbeat_us > StoreLeaseUs())
          lapsed.push_back(n);
    }
    for (const db::NodeRecord& n : silent)
      DeclareDown(n, now, "simulation node " + n.name + " stopped answering", {});
    for (db::NodeRecord n : lapsed) {  // its lease ran out in the store: heard by no one
      const int64_t written = n.heartbeat_us;
      n.heartbeat_us = now - StoreLeaseUs() - 1;
      DeclareDown(n, now, "simulation node " + n.name + " stopped answering (its lease lapsed)",
                  {{"lease_written_ms_ago", (now - written) / 1000}});
    }
    if (late.empty()) continue;
    std::lock_guard lock(stop_mutex);
    to_probe = std::move(late);
    stop_cv.notify_all();
  }
}

void ClusterSessions::Impl::ProberLoop() {
  for (;;) {
    std::vector<db::NodeRecord> late;
    {
      std::unique_lock lock(stop_mutex);
      stop_cv.wait(lock, [&] { return stopping || !to_probe.empty(); });
      if (stopping) return;
      late.swap(to_probe);
    }
    for (db::NodeRecord n : late) {
      if (ProbeListening(n.grpc_address, kProbeTimeoutS) != Listening::kRefused) continue;
      {
        // Down unless a heartbeat came after the one this decision read.
        std::lock_guard lock(heard_mutex);
        const auto it = heard.find(n.name);
        if (it == heard.end() || it->second.heard_us != n.heartbeat_us) continue;
      }
      DeclareDown(n, db::NowUs(),
                  "simulation node " + n.name + " stopped answering (its port refuses connections)",
                  {{"refused", "1"}});
    }
  }
}

}  // namespace vsurg::server::cluster
