// The control role: placement, the nodes' registry and watchdog, the nodes' telemetry.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

#include <grpcpp/health_check_service_interface.h>

#include "common/core/log.h"
#include "common/core/realtime.h"
#include "db/store.h"
#include "server/cluster/cluster_common.h"
#include "server/ops/metrics.h"
#include "server/session/caller_deadline.h"

namespace vsurg::server::cluster {
namespace {

void Log(const std::string& event, const LogFields& fields = {}) {
  LogEvent("vsurg-control", event, fields);
}

Error NotLive(uint64_t id) {
  return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
}

}  // namespace

struct ClusterSessions::Impl final : public v1::ClusterService::Service {
  db::Store& store;
  ClusterOptions options;
  // Placement decisions (for Collect): sessions placed per node, and the refusals by reason.
  mutable std::mutex placements_mutex;
  std::map<std::string, uint64_t> placed;
  // trainee_limit, no_room, invalid_request, node_failed, caller_gone
  std::map<std::string, uint64_t> refused;
  std::map<std::string, uint64_t> migrations;  // moved, refused (by a node), no_room
  // Creates waiting on a node (ClusterSessions::Create), cancelled when this replica declares the
  // node down: each is placed on another node within the same call, instead of waiting out the
  // create timeout on a node that will never answer (a frozen one).
  std::mutex creating_mutex;
  std::multimap<std::string, grpc::ClientContext*> creating;
  void CancelCreatesOn(const std::string& node) {
    std::lock_guard lock(creating_mutex);
    const auto [first, last] = creating.equal_range(node);
    for (auto it = first; it != last; ++it) it->second->TryCancel();
  }

  // A session created for a caller that has gone (ClusterSessions::Create): aborted on its node
  // at once (NodeStopRequest.abandoned), with its own deadline, the caller's having passed. A
  // node that does not answer leaves it to its not-started timeout.
  void Abandon(const db::NodeRecord& node, uint64_t id) {
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

  void Count(std::map<std::string, uint64_t>& m, const std::string& key) {
    std::lock_guard lock(placements_mutex);
    ++m[key];
  }

  TlsFiles tls;  // before the server and channels that use it
  std::unique_ptr<grpc::Server> server, health;
  int health_port = 0;
  int port = 0;

  std::mutex stubs_mutex;
  // By node name and address: with TLS the channel checks that the address serves that name.
  std::map<std::pair<std::string, std::string>, std::unique_ptr<v1::NodeService::Stub>> stubs;

  std::mutex subscribers_mutex;  // held while subscribers run (see Unsubscribe)
  struct Subscription {
    uint64_t session = 0;
    Subscriber fn;
    bool ended = false;
  };
  std::map<uint64_t, Subscription> subscribers;
  uint64_t next_token = 1;

  // This replica's placements the store may not show yet, so that a burst of stations placed at
  // once does not pile onto the node that was emptiest when they all read the rows. In flight:
  // a Create sent to the node and not answered (the node writes the row just before it
  // answers). Answered: numbered in order with their session ids; one answered after a
  // placement began its read, and missing from that read, is counted once (one answered before
  // the read began is in it while it is live). The store is read outside the lock, so
  // placements do not queue behind each other's queries.
  mutable std::mutex placing_mutex;
  std::map<std::string, int> in_flight;
  struct Answered {
    uint64_t number;
    int64_t id;
    std::string node;
  };
  uint64_t answered_count = 0;
  std::deque<Answered> answered;  // the last kAnswered, oldest first
  static constexpr size_t kAnswered = 1024;
  // A Create in flight may already have written its row (the node commits, then answers), so a
  // read can list it while it is still counted in flight. Seen: live session ids read or
  // answered before. A listed id not seen yet, on a node with placements in flight, is held as
  // unexplained until those are answered; up to one unexplained row per Create in flight is
  // taken to be that Create's and not counted twice. (Another replica's session placed on the
  // same node at the same moment is taken for one of ours: one too few for that moment.)
  std::set<int64_t> seen;
  std::map<std::string, std::set<int64_t>> unexplained;  // by node
  static constexpr size_t kSeen = 65536;

  uint64_t AnsweredCount() {
    std::lock_guard lock(placing_mutex);
    return answered_count;
  }

  // Least loaded first: live sessions (the store's `rows`, read after `answered_before`
  // placements were answered, and this replica's it may not show yet) for the capacity, then
  // CPU, then the name (a stable order); nodes in `tried` are skipped. The choice is reserved
  // (in flight) before the lock is let go; Release ends the reservation. `with_room` counts the
  // nodes that are up, not draining and below capacity, tried or not.
  std::optional<db::NodeRecord> Reserve(const std::vector<db::NodeRecord>& nodes,
                                        const std::vector<std::pair<std::string, int64_t>>& rows,
                                        uint64_t answered_before,
                                        const std::vector<std::string>& tried, size_t& with_room) {
    std::map<std::string, int> by_node;
    std::set<int64_t> listed;
    for (const auto& [node, id] : rows) ++by_node[node], listed.insert(id);
    const int64_t now = db::NowUs();
    std::lock_guard lock(placing_mutex);
    for (const Answered& a : answered)
      if (a.number > answered_before && !listed.count(a.id)) ++by_node[a.node];
    for (const auto& [node, id] : rows)
      if (!seen.count(id)) {
        if (in_flight.count(node))
          unexplained[node].insert(id);
        else
          seen.insert(id);
      }
    for (const auto& [node, n] : in_flight) {
      size_t mine = 0;  // rows this read lists that are (taken to be) Creates still in flight
      for (int64_t id : unexplained[node]) mine += listed.count(id);
      by_node[node] += n - static_cast<int>(std::min<size_t>(mine, static_cast<size_t>(n)));
    }
    if (seen.size() > kSeen) {  // ended sessions never come back: keep the live and answered
      seen = listed;
      for (const Answered& a : answered) seen.insert(a.id);
    }
    const db::NodeRecord* best = nullptr;
    double best_load = 0;
    with_room = 0;
    for (const db::NodeRecord& n : nodes) {
      const int sessions = by_node[n.name];
      if (!Healthy(n, now) || n.draining || sessions >= n.capacity) continue;
      ++with_room;
      if (std::find(tried.begin(), tried.end(), n.name) != tried.end()) continue;
      const double load = static_cast<double>(sessions) / n.capacity;
      if (!best || load < best_load ||
          (load == best_load &&
           (n.cpu < best->cpu || (n.cpu == best->cpu && n.name < best->name)))) {
        best = &n;
        best_load = load;
      }
    }
    if (!best) return std::nullopt;
    ++in_flight[best->name];
    return *best;
  }

  // The node answered `node`'s Create: with the new session's id, or nullopt when it refused.
  void Release(const std::string& node, std::optional<int64_t> session) {
    std::lock_guard lock(placing_mutex);
    if (--in_flight[node] == 0) {
      in_flight.erase(node);
      auto held = unexplained.extract(node);  // nothing in flight there: explained
      if (!held.empty()) seen.merge(held.mapped());
    }
    if (!session) return;
    seen.insert(*session);
    if (auto it = unexplained.find(node); it != unexplained.end()) it->second.erase(*session);
    answered.push_back({++answered_count, *session, node});
    if (answered.size() > kAnswered) answered.pop_front();
  }

  std::mutex stop_mutex;
  std::condition_variable stop_cv;
  bool stopping = false;
  std::vector<db::NodeRecord> to_probe;  // late nodes, for the prober (under stop_mutex)
  std::thread watchdog, prober, poller;
  std::once_flag shutdown_once;

  Impl(db::Store& s, const ClusterOptions& o) : store(s), options(o) {}

  // A node call that reads on a caller's behalf (Join, a surface, a record): no longer than the
  // caller still waits (caller_deadline.h), at most call_timeout_s.
  std::unique_ptr<grpc::ClientContext> ReadContext() const {
    return CallContext(options.token, CallerDeadline::Left(options.call_timeout_s));
  }
  int64_t TimeoutUs() const { return static_cast<int64_t>(options.heartbeat_timeout_s * 1e6); }
  int64_t PeriodUs() const { return static_cast<int64_t>(options.heartbeat_period_s * 1e6); }
  // The lease a node's row in the store carries (its heartbeat_us: when it was written), never
  // shorter than the heartbeat timeout.
  int64_t StoreLeaseUs() const {
    return static_cast<int64_t>(std::max(options.store_lease_s, options.heartbeat_timeout_s) * 1e6);
  }
  // The row is rewritten once less than this is left of its lease: half of it (a write may take
  // seconds on a loaded store), and at least a timeout and two periods.
  int64_t RenewAheadUs() const {
    return std::max(StoreLeaseUs() / 2, TimeoutUs() + 2 * PeriodUs());
  }

  // --- Heartbeats in memory (docs/SCALING.md, "Heartbeats and the store") ---
  // A node's heartbeats go to one replica (its channel picks the first that answers). That
  // replica keeps them here and writes the node's row only when half the row's lease is gone
  // (one heartbeat does the write; the others are answered from memory meanwhile, as long as
  // every lease so granted ends before the row's: no other replica can declare the node down
  // while it serves), when the node began beating here (a new process, a new epoch, or a node
  // that came from another replica: that write is what tells the other replica it is no longer
  // silent), or when what placement reads changed (draining, capacity, addresses). Declaring a node
  // down is then this replica's to do for the nodes it hears (silent a heartbeat timeout), and any
  // replica's for a row whose lease has run out (its replica is gone too).
  struct Heard {
    std::string instance;
    int64_t epoch = 0;
    int64_t heard_us = 0;    // the last heartbeat, on this replica's clock
    int64_t written_us = 0;  // the row's last write by this replica
    db::NodeRecord last;     // the last heartbeat's facts
    // The watchdog is declaring it down: heartbeats go to the store (ordered against that
    // transaction) until it has.
    bool condemned = false;
    bool renewing = false;  // a heartbeat is rewriting the row now
  };
  mutable std::mutex heard_mutex;
  std::map<std::string, Heard> heard;  // by node name
  std::atomic<uint64_t> beats_received{0}, beats_written{0};

  static bool PlacementFactsChanged(const db::NodeRecord& a, const db::NodeRecord& b) {
    return a.draining != b.draining || a.capacity != b.capacity ||
           a.grpc_address != b.grpc_address || a.udp_host != b.udp_host ||
           a.udp_port != b.udp_port || a.started_us != b.started_us;
  }

  // Up: not marked down, and heard from within the timeout (a node this replica hears) or
  // holding an unexpired lease in the store (one another replica hears).
  bool Healthy(const db::NodeRecord& n, int64_t now) const {
    if (n.down) return false;
    std::lock_guard lock(heard_mutex);
    const auto it = heard.find(n.name);
    if (it != heard.end() && it->second.instance == n.instance && it->second.epoch == n.epoch)
      return now - it->second.heard_us <= TimeoutUs();
    return now - n.heartbeat_us <= StoreLeaseUs();
  }

  v1::NodeService::Stub& StubFor(const db::NodeRecord& node) {
    std::lock_guard lock(stubs_mutex);
    auto& s = stubs[{node.name, node.grpc_address}];
    if (!s) s = v1::NodeService::NewStub(Channel(node.grpc_address, tls, node.name));
    return *s;
  }

  // The node a session runs on, when it is up.
  Expected<std::pair<db::SessionRecord, db::NodeRecord>> NodeOf(uint64_t id) {
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
                 "session " + std::to_string(id) + " has no known node ('" + row->node + "')",
                 "id"};
  }

  template <class Call>
  Expected<db::SessionRecord> OnNode(uint64_t id, const char* what, Call&& call) {
    auto at = NodeOf(id);
    if (!at.ok()) return at.error();
    v1::NodeSession reply;
    auto ctx = CallContext(options.token, options.call_timeout_s);
    const grpc::Status s = call(StubFor(at->second), ctx.get(), &reply);
    if (!s.ok()) return FromGrpc(s, std::string(what) + " on node " + at->second.name);
    db::SessionRecord r = FromProto(reply.session());
    r.node = at->second.name;
    return r;
  }

  // --- ClusterService ---
  static grpc::Status ToGrpc(const Error& e) {
    grpc::StatusCode code = grpc::StatusCode::UNAVAILABLE;
    if (e.code == ErrorCode::kInvalidArgument) code = grpc::StatusCode::INVALID_ARGUMENT;
    if (e.code == ErrorCode::kAlreadyExists) code = grpc::StatusCode::ALREADY_EXISTS;
    if (e.code == ErrorCode::kFailedPrecondition) code = grpc::StatusCode::FAILED_PRECONDITION;
    return grpc::Status(code, e.message);
  }

  // The site's token, and with TLS a certificate that names the node the call speaks for: a
  // process may take or renew only the name its certificate carries.
  grpc::Status Allowed(const grpc::ServerContext& ctx, const std::string& node) const {
    if (!Authorized(ctx, options.token))
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "no valid cluster token");
    grpc::Status s = CheckPeer(ctx, options, node, "node " + node);
    if (s.ok() && options.tls() && node == options.control_name)  // a control replica's cert
      s = grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                       "'" + node + "' is the control replicas' name, not a node's");
    if (!s.ok()) Log("node_refused", {{"node", node}, {"error", s.error_message()}});
    return s;
  }

  grpc::Status Acquire(grpc::ServerContext* ctx, const v1::NodeHeartbeat* req,
                       v1::NodeLeaseReply* out) override {
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

  // A draining node's session to another node: placed as a new session is (the least loaded
  // node up, not draining, with room; a node that refuses is skipped for the next), and adopted
  // there. The adopting node makes the store's row its own (Store::MoveSession, fenced by both
  // nodes' epochs), so a sender the site gave up on moves nothing.
  grpc::Status Migrate(grpc::ServerContext* ctx, const v1::NodeHandoff* req,
                       v1::NodeMoved* out) override {
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
      const uint64_t answered_before = AnsweredCount();
      auto nodes = store.ListNodes();
      if (!nodes.ok()) return ToGrpc(nodes.error());
      auto rows = store.LiveSessionNodes();
      if (!rows.ok()) return ToGrpc(rows.error());
      const auto reserved = Reserve(*nodes, *rows, answered_before, tried_nodes, with_room);
      if (!reserved) break;
      tried_nodes.push_back(reserved->name);
      v1::NodeSession reply;
      auto call = CallContext(options.token, options.create_timeout_s);
      const grpc::Status s = StubFor(*reserved).Adopt(call.get(), *req, &reply);
      Release(reserved->name, s.ok() ? std::optional<int64_t>(reply.session().id()) : std::nullopt);
      if (s.ok()) {
        Count(migrations, "moved");
        out->set_node(reserved->name);
        out->set_udp_host(reply.udp_host());
        out->set_udp_port(reply.udp_port());
        Log("session_migrated",
            {{"session", req->id()}, {"from", req->from_node()}, {"to", reserved->name}});
        return grpc::Status::OK;
      }
      Count(migrations, "refused");
      tried += (tried.empty() ? "" : "; ") + reserved->name + ": " + s.error_message();
      // The session or the sender is the reason (the session ended meanwhile, the sender lost
      // its lease): no other node would do better.
      if (s.error_code() == grpc::StatusCode::FAILED_PRECONDITION &&
          s.error_message().find("move refused") != std::string::npos)
        return s;
    }
    Count(migrations, "no_room");
    return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "no other simulation node takes session " + std::to_string(req->id()) +
                            " (" + std::to_string(with_room) + " with room" +
                            (tried.empty() ? "" : ": " + tried) + ")");
  }

  grpc::Status Heartbeat(grpc::ServerContext* ctx, const v1::NodeHeartbeat* req,
                         v1::HeartbeatReply* out) override {
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

  bool WaitFor(double seconds) {  // false once stopping
    std::unique_lock lock(stop_mutex);
    return !stop_cv.wait_for(lock, std::chrono::microseconds(static_cast<int64_t>(seconds * 1e6)),
                             [&] { return stopping; });
  }

  // The node `n` (as this replica last heard it, its last heartbeat at `n.heartbeat_us`) is
  // declared down unless a heartbeat came since: the row is written by the first heartbeat any
  // replica gets after this decision (the condemned flag sends them to the store), so either
  // that write or this transaction comes first and the other sees it.
  void DeclareDown(const db::NodeRecord& n, int64_t now, const std::string& reason,
                   LogFields fields) {
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

  void WatchdogLoop() {
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

  // A heartbeat late by half a period may be a loaded node, a slow network, or a process that
  // is gone. The last is certain when its gRPC port refuses connections: nothing listens there,
  // and the sessions lived in that process. Such a node is down at once (its stations are back
  // about a second and a half sooner); any other answer, or none, leaves it to the timeout. The
  // probes run on their own thread, so a slow one (DNS, a host that drops packets) never holds
  // up the timeout's sweep.
  int64_t LateUs() const { return static_cast<int64_t>(options.heartbeat_period_s * 1.5e6); }

  void ProberLoop() {
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
        DeclareDown(
            n, db::NowUs(),
            "simulation node " + n.name + " stopped answering (its port refuses connections)",
            {{"refused", "1"}});
      }
    }
  }
  static constexpr double kProbeTimeoutS = 0.2;

  // --- Telemetry: one stream per node, only what someone on this replica watches ---
  // What a replica watches on one node: every session's figures (a watcher of all sessions:
  // the live overview, a metrics scrape), or only some; and the surfaces of the sessions someone
  // views. Watched only while subscribed; nothing is asked of a node no one here watches.
  struct WatchSpec {
    bool all = false;
    std::set<uint64_t> sessions, surfaces;
    bool operator==(const WatchSpec&) const = default;
  };
  // One NodeService.Watch call and the thread reading it. The reader keeps the latest message's
  // sessions, each with the last surface it got (a surface comes once per new frame).
  struct NodeStream {
    std::string address;
    WatchSpec spec;
    std::unique_ptr<grpc::ClientContext> ctx;
    std::thread reader;
    std::mutex mutex;
    std::map<uint64_t, SessionTelemetry> latest;
    std::chrono::steady_clock::time_point last_message{};
    bool done = false;  // the call ended (the node stopped, or refused): opened again
  };
  std::map<std::string, std::unique_ptr<NodeStream>> streams;  // by node; the poller's own
  std::atomic<uint64_t> watch_bytes{0}, watch_opened{0};
  std::atomic<int> streams_open{0};

  void OpenStream(const std::string& node, const db::NodeRecord& n, WatchSpec spec) {
    auto st = std::make_unique<NodeStream>();
    st->address = n.grpc_address;
    st->spec = std::move(spec);
    st->ctx = CallContext(options.token, 0);
    st->last_message = std::chrono::steady_clock::now();
    v1::NodeWatchRequest req;
    req.set_all(st->spec.all);
    for (uint64_t id : st->spec.sessions) req.add_sessions(id);
    for (uint64_t id : st->spec.surfaces) req.add_surfaces(id);
    req.set_rate_hz(options.telemetry_hz);
    NodeStream* p = st.get();
    std::shared_ptr<grpc::ClientReader<v1::NodeTelemetry>> reader =
        StubFor(n).Watch(p->ctx.get(), req);
    watch_opened.fetch_add(1, std::memory_order_relaxed);
    p->reader = std::thread([this, p, reader] {
      NameThisThread("vsurg-watch");
      v1::NodeTelemetry msg;
      while (reader->Read(&msg)) {
        watch_bytes.fetch_add(msg.ByteSizeLong(), std::memory_order_relaxed);
        std::map<uint64_t, SessionTelemetry> next;
        for (const v1::Telemetry& t : msg.sessions()) next[t.session_id()] = convert::FromProto(t);
        std::lock_guard lock(p->mutex);
        for (auto& [id, t] : next) {
          const auto old = p->latest.find(id);
          if (!t.has_surface && old != p->latest.end() && old->second.has_surface) {
            t.has_surface = true;
            t.surface_frame = old->second.surface_frame;
            t.surface_indices = std::move(old->second.surface_indices);
            t.surface_positions = std::move(old->second.surface_positions);
          }
        }
        p->latest = std::move(next);
        p->last_message = std::chrono::steady_clock::now();
      }
      reader->Finish();
      std::lock_guard lock(p->mutex);
      p->done = true;
      p->latest.clear();
    });
    streams[node] = std::move(st);
    streams_open.store(static_cast<int>(streams.size()), std::memory_order_relaxed);
  }

  void CloseStream(std::map<std::string, std::unique_ptr<NodeStream>>::iterator it) {
    it->second->ctx->TryCancel();
    if (it->second->reader.joinable()) it->second->reader.join();
    streams.erase(it);
    streams_open.store(static_cast<int>(streams.size()), std::memory_order_relaxed);
  }

  // The streams this replica's watchers need: every up node's for a watcher of all sessions, a
  // watched session's node's for one session (with its surface). Store reads only.
  void Reconcile(bool all, const std::set<uint64_t>& watched) {
    std::map<std::string, WatchSpec> want;
    std::map<std::string, db::NodeRecord> up;
    auto nodes = store.ListNodes();
    if (!nodes.ok()) return;  // keep what runs
    const int64_t now = db::NowUs();
    for (const db::NodeRecord& n : *nodes)
      if (Healthy(n, now)) {
        up[n.name] = n;
        if (all) want[n.name].all = true;
      }
    for (uint64_t id : watched) {
      auto row = store.GetSession(static_cast<int64_t>(id));
      if (!row.ok() || !vsurg::IsLive(row->state) || !up.count(row->node)) continue;
      WatchSpec& w = want[row->node];
      if (!w.all) w.sessions.insert(id);
      w.surfaces.insert(id);
    }
    for (auto it = streams.begin(); it != streams.end();) {
      auto next = std::next(it);
      const auto w = want.find(it->first);
      bool done;
      {
        std::lock_guard lock(it->second->mutex);
        done = it->second->done;
      }
      if (w == want.end() || !(w->second == it->second->spec) || done ||
          up[it->first].grpc_address != it->second->address)
        CloseStream(it);
      it = next;
    }
    for (auto& [node, w] : want)
      if (!streams.count(node)) OpenStream(node, up[node], std::move(w));
  }

  void PollerLoop() {
    const double period = 1.0 / options.telemetry_hz;
    // A stream silent this long is a node frozen or cut off: its sessions are left out (their
    // watchers get nothing from it) until it speaks again or the watchdog declares it down.
    const auto silent =
        std::chrono::microseconds(static_cast<int64_t>(std::max(0.5, 3 * period) * 1e6));
    const int reconcile_every = std::max(1, static_cast<int>(0.2 / period));  // 5 times a second
    int tick = 0;
    std::optional<std::pair<bool, std::set<uint64_t>>> last;
    while (WaitFor(period)) {
      std::pair<bool, std::set<uint64_t>> watch;
      {
        std::lock_guard lock(subscribers_mutex);
        for (const auto& [token, sub] : subscribers) {
          if (sub.ended) continue;
          if (sub.session == 0)
            watch.first = true;
          else
            watch.second.insert(sub.session);
        }
      }
      if (!watch.first && watch.second.empty()) {
        while (!streams.empty()) CloseStream(streams.begin());
        last.reset();
        continue;
      }
      if (!last || *last != watch || ++tick % reconcile_every == 0) {
        Reconcile(watch.first, watch.second);
        last = watch;
      }
      std::vector<SessionTelemetry> all;
      const auto now = std::chrono::steady_clock::now();
      for (auto& [node, st] : streams) {
        std::lock_guard lock(st->mutex);
        if (now - st->last_message > silent) continue;
        for (const auto& [id, t] : st->latest) all.push_back(t);
      }
      std::lock_guard lock(subscribers_mutex);
      for (auto& [token, sub] : subscribers) {
        if (sub.ended) continue;
        if (sub.session == 0) {
          sub.fn(all, false);
          continue;
        }
        std::vector<SessionTelemetry> one;
        for (const SessionTelemetry& t : all)
          if (t.id == sub.session) one.push_back(t);
        if (!one.empty()) {
          sub.fn(one, false);
          continue;
        }
        // Not on any node's stream now: ended (or its node is gone), unless the store still
        // says live (a stream just opened, or a node that missed a beat).
        auto row = store.GetSession(static_cast<int64_t>(sub.session));
        if (row.ok() && vsurg::IsLive(row->state)) continue;
        sub.ended = true;
        sub.fn({}, true);
      }
    }
    while (!streams.empty()) CloseStream(streams.begin());
  }
};

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
  if (!(options.telemetry_hz >= 1 && options.telemetry_hz <= 120))
    return InvalidArgument("telemetry-hz", "must be within 1..120");
  auto tls = WatchTlsFiles(options);
  if (!tls.ok()) return tls.error();
  auto impl = std::make_unique<Impl>(store, options);
  impl->tls = std::move(tls).value();
  auto creds = ServerCredentials(options, impl->tls);
  if (!creds.ok()) return creds.error();
  // The sessions live before this replica started are explained (see Impl::seen).
  if (auto live = store.LiveSessionNodes(); live.ok())
    for (const auto& [node, id] : *live) impl->seen.insert(id);
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
    const uint64_t answered_before = d.AnsweredCount();
    auto nodes = d.store.ListNodes();
    if (!nodes.ok()) return nodes.error();
    auto rows = d.store.LiveSessionNodes();
    if (!rows.ok()) return rows.error();
    registered = nodes->size();
    const auto reserved = d.Reserve(*nodes, *rows, answered_before, tried_nodes, with_room);
    if (!reserved) break;
    const db::NodeRecord& chosen = *reserved;
    tried_nodes.push_back(chosen.name);
    v1::NodeCreateRequest req;
    req.set_trainee(trainee);
    req.set_scene(scene);
    convert::ToProto(task, req.mutable_task());
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
    d.Release(chosen.name, s.ok() ? std::optional<int64_t>(reply.session().id()) : std::nullopt);
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

Expected<CreatedSession> ClusterSessions::Join(uint64_t id, bool with_surface) {
  auto at = impl_->NodeOf(id);
  if (!at.ok()) return at.error();
  if (!vsurg::IsLive(at->first.state)) return NotLive(id);
  v1::JoinRequest req;
  req.set_id(id);
  req.set_with_surface(with_surface);
  v1::NodeSession reply;
  auto ctx = impl_->ReadContext();
  const grpc::Status s = impl_->StubFor(at->second).Join(ctx.get(), req, &reply);
  if (!s.ok()) return FromGrpc(s, "join on node " + at->second.name);
  CreatedSession out = FromProto(reply);
  out.record.node = at->second.name;
  return out;
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

uint64_t ClusterSessions::Subscribe(uint64_t session, Subscriber fn) {
  std::lock_guard lock(impl_->subscribers_mutex);
  const uint64_t token = impl_->next_token++;
  impl_->subscribers[token] = {session, std::move(fn), false};
  return token;
}

void ClusterSessions::Unsubscribe(uint64_t token) {
  std::lock_guard lock(impl_->subscribers_mutex);  // waits for a delivery in progress
  impl_->subscribers.erase(token);
}

void ClusterSessions::Collect(ops::MetricsText& m) const {
  const Impl& d = *impl_;
  {
    std::lock_guard lock(d.placing_mutex);
    m.Family("vsurg_placements_in_flight", "gauge",
             "Creates this replica sent to a node and has no answer for yet, by node (the node "
             "builds their scenes, or does not answer).");
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
