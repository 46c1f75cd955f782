// The control role's private parts, shared by its rooms: cluster_sessions.cpp (the Sessions
// API over the nodes, metrics, start and shutdown), cluster_placement.cpp (placement and live
// migration), cluster_registry.cpp (the nodes' leases, heartbeats and watchdog),
// cluster_telemetry.cpp (the nodes' telemetry streams). Not included outside server/cluster/.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/core/log.h"
#include "db/store.h"
#include "proto/convert/services.h"
#include "server/cluster/cluster.h"
#include "server/cluster/cluster_common.h"
#include "server/session/caller_deadline.h"

namespace vsurg::server::cluster {

struct ClusterSessions::Impl final : public v1::ClusterService::Service {
  static void Log(const std::string& event, const LogFields& fields = {}) {
    LogEvent("vsurg-control", event, fields);
  }
  static Error NotLive(uint64_t id) {
    return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
  }

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
  void Abandon(const db::NodeRecord& node, uint64_t id);

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

  // Placement (cluster_placement.cpp): each Create reserves its node in the store first
  // (db::Store::ReservePlacement, one at a time across every replica), so a burst of stations
  // placed at once through several replicas never piles onto the node that was emptiest when
  // they all read the rows. In flight here: Creates and moves this replica sent to a node and has
  // no answer for yet (a metric).
  mutable std::mutex placing_mutex;
  std::map<std::string, int> in_flight;

  // Least loaded first (the store's load: live sessions and reservations) for the capacity,
  // then CPU, then the name (a stable order); nodes in `tried` are skipped. The choice is
  // reserved before the store's lock is let go; Release ends the reservation. `with_room` counts
  // the nodes that are up, not draining and below capacity, tried or not.
  Expected<std::optional<std::pair<db::NodeRecord, std::string>>> Reserve(
      const std::vector<db::NodeRecord>& nodes, const std::vector<std::string>& tried,
      size_t& with_room);
  // The node answered (or failed) the placement `token` on `node`.
  void Release(const std::string& node, const std::string& token);

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
  bool Healthy(const db::NodeRecord& n, int64_t now) const;

  v1::NodeService::Stub& StubFor(const db::NodeRecord& node);

  // The node a session runs on, when it is up.
  Expected<std::pair<db::SessionRecord, db::NodeRecord>> NodeOf(uint64_t id);

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
  static grpc::Status ToGrpc(const Error& e);

  // The site's token, and with TLS a certificate that names the node the call speaks for: a
  // process may take or renew only the name its certificate carries.
  grpc::Status Allowed(const grpc::ServerContext& ctx, const std::string& node) const;

  grpc::Status Acquire(grpc::ServerContext* ctx, const v1::NodeHeartbeat* req,
                       v1::NodeLeaseReply* out) override;

  // A draining node's session to another node: placed as a new session is (the least loaded
  // node up, not draining, with room; a node that refuses is skipped for the next), and adopted
  // there. The adopting node makes the store's row its own (Store::MoveSession, fenced by both
  // nodes' epochs), so a sender the site gave up on moves nothing.
  grpc::Status Migrate(grpc::ServerContext* ctx, const v1::NodeHandoff* req,
                       v1::NodeMoved* out) override;

  grpc::Status Heartbeat(grpc::ServerContext* ctx, const v1::NodeHeartbeat* req,
                         v1::HeartbeatReply* out) override;

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
                   LogFields fields);

  void WatchdogLoop();

  // A heartbeat late by half a period may be a loaded node, a slow network, or a process that
  // is gone. The last is certain when its gRPC port refuses connections: nothing listens there,
  // and the sessions lived in that process. Such a node is down at once (its stations are back
  // about a second and a half sooner); any other answer, or none, leaves it to the timeout. The
  // probes run on their own thread, so a slow one (DNS, a host that drops packets) never holds
  // up the timeout's sweep.
  int64_t LateUs() const { return static_cast<int64_t>(options.heartbeat_period_s * 1.5e6); }

  void ProberLoop();
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

  void OpenStream(const std::string& node, const db::NodeRecord& n, WatchSpec spec);

  void CloseStream(std::map<std::string, std::unique_ptr<NodeStream>>::iterator it);

  // The streams this replica's watchers need: every up node's for a watcher of all sessions, a
  // watched session's node's for one session (with its surface). Store reads only.
  void Reconcile(bool all, const std::set<uint64_t>& watched);

  void PollerLoop();
};

}  // namespace vsurg::server::cluster
