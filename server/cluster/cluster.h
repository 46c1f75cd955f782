// Beyond one machine (DESIGN.md): the two roles besides the all-in-one server.
//
//   control  ClusterSessions: the control plane's Sessions for a site. New sessions are placed
//            on a healthy simulation node with room (fewest live sessions for its capacity,
//            then least CPU); the station gets that node's UDP address and the session key.
//            Serves ClusterService (the nodes' heartbeats, kept in memory with a lease written
//            to the shared store every few seconds) on an internal port; a watchdog marks a node
//            silent for 2 s down and aborts its sessions
//            (MarkNodeDown: once, whichever replica sees it first), or at once when its
//            heartbeat is late and its port refuses connections (its process is gone). Monitors and
//            the dashboard get the nodes' telemetry through it: one NodeService.Watch stream per
//            node while someone on this replica watches, carrying only what is watched (every
//            session's figures for an overview or a scrape; a session's surface only while
//            someone views it). Stateless: every fact is in the store, so replicas run side by
//            side.
//   sim      NodeAgent: a SessionManager's sessions offered to the control plane (NodeService on
//            an internal port), and a heartbeat every 0.5 s with the node's load. Drain: no new
//            sessions, the live ones finish (SIGTERM, a rolling upgrade).
//
// Leases and fencing (store.h design note 7, server/net/lease.h). A node first acquires its
// name (ClusterService.Acquire: refused while another live process holds it; a new epoch, and
// the sessions earlier holders left aborted); each heartbeat renews the lease for the heartbeat
// timeout from when it was sent, less a margin. While the lease is lapsed the node answers no
// stylus datagram and takes no session; when a heartbeat is refused (the site declared the node
// down, or a newer process took the name) it drops every session without writing it and
// acquires the name again. Every store write of a session carries the epoch it was created
// under, and the store refuses a stale one: a node the site gave up on never serves or records
// its old sessions again.
//
// Internal calls carry the site's cluster token (`authorization: Bearer …`); users never reach
// these ports. With mutual TLS (ClusterOptions::tls_*), each side also proves who it is by its
// certificate: a node may only acquire or beat for the name its certificate carries, only a
// control replica's certificate may call a node, and each side checks the other's name when it
// connects. No gRPC or protobuf type appears in this header.
//
// Threads: ClusterSessions has a watchdog thread (0.1 s), a prober for late nodes, a telemetry
// thread (delivers to subscribers at telemetry_hz and opens and closes the node streams), one
// reader thread per open node stream, and gRPC's threads for heartbeats; every member may be
// called from any thread. A node's Watch stream holds one of its gRPC threads while it lasts.
// NodeAgent has a heartbeat thread and gRPC's threads. With TLS each also has gRPC's file-watcher
// thread for its certificate files.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "common/core/expected.h"
#include "common/core/range.h"
#include "server/session/sessions.h"

namespace vsurg::db {
class Store;
}

namespace vsurg::server {
class Lease;
class SessionManager;
}  // namespace vsurg::server

namespace vsurg::server::ops {
class MetricsText;
}

namespace vsurg::server::cluster {

struct ClusterOptions {
  // The bounds checked at start (and shown by vsurg-server's options).
  static constexpr Range kTlsRefreshS{1, 86400}, kStoreLeaseS{2, 300}, kHeartbeatPeriodS{0.05, 10},
      kHeartbeatTimeoutS{0.1, 120}, kTelemetryHz{1, 120};
  std::string token;            // the site's cluster secret (≥ 16 characters)
  std::string listen;           // the internal API's host:port (port 0: any free one)
  bool allow_insecure = false;  // plaintext off loopback (a cluster network; see SCALING.md)
  // Mutual TLS on the internal API (docs/SCALING.md, "Mutual TLS"): this process's certificate
  // chain and key and the site's CA bundle, PEM files all three or none. Both sides present a
  // certificate the CA signed; a node's must name the node (a DNS subject alternative name or
  // the common name equal to --node-name), a control replica's must name `control_name`. The
  // files are read again every tls_refresh_s: a renewed certificate or CA bundle is used for the
  // next connections without a restart.
  std::string tls_cert, tls_key, tls_ca;
  std::string control_name = "vsurg-control";
  double tls_refresh_s = 60;
  // With TLS, the gRPC health check (what Kubernetes' probes use) on its own plaintext port:
  // liveness only, no service and no data (empty: none).
  std::string health_listen;
  bool tls() const { return !tls_cert.empty() || !tls_key.empty() || !tls_ca.empty(); }
  double heartbeat_period_s = 0.5;
  double heartbeat_timeout_s = 2;  // silent this long: down, sessions aborted (= the lease)
  // The lease a node's row in the store carries. The replica a node beats to keeps the beats in
  // memory and rewrites the row when half of this is gone (every 5 s by default, instead of
  // every 0.5 s); any replica declares down a node whose row lease lapsed (it and the replica
  // it beat to are gone). At or below the timeout plus a period, every heartbeat is written.
  double store_lease_s = 10;
  // A node's lease ends this long before the control plane may declare it down (server/net/
  // lease.h): the most the control replicas' clocks may disagree with each other.
  double lease_margin_s = 0.25;
  double telemetry_hz = 30;
  int max_sessions_per_user = 2;  // live sessions per trainee, over the whole site
  double create_timeout_s = 60;   // a node builds the scene before it answers Create
  double call_timeout_s = 5;
};

class ClusterSessions final : public Sessions {
 public:
  static Expected<std::unique_ptr<ClusterSessions>> Start(db::Store& store,
                                                          const ClusterOptions& options);
  ~ClusterSessions() override;  // Shutdown()
  int port() const;             // the internal API's
  int health_port() const;      // the plaintext health check's (0: none)

  Expected<CreatedSession> Create(const std::string& trainee, const std::string& scene,
                                  const scoring::TaskSettings& task = {}) override;
  Expected<db::SessionRecord> Start(uint64_t id) override;
  Expected<db::SessionRecord> Stop(uint64_t id, const std::string& reason) override;
  Expected<db::SessionRecord> Get(uint64_t id) override;
  Expected<CreatedSession> Join(uint64_t id, bool with_surface) override;
  Expected<CreatedSession> JoinInstructor(uint64_t id, const std::string& instructor) override;
  Status LeaveInstructor(uint64_t id, const std::string& instructor) override;
  Expected<SessionGuidance> Guide(uint64_t id, const std::string& instructor,
                                  const sim::GuideRequest& request) override;
  Expected<SessionGuidance> Guidance(uint64_t id) const override;
  Status RestSurface(uint64_t id, std::vector<geometry::Vec3>& positions,
                     std::vector<int32_t>& triangles) const override;
  Expected<std::string> Trace(uint64_t id) const override;
  bool IsLive(uint64_t id) const override;
  int EndSessionsOf(const std::string& user, const std::string& reason) override;
  uint64_t Subscribe(uint64_t session, Subscriber fn) override;
  void Unsubscribe(uint64_t token) override;
  // Stops the internal API and the threads; the nodes' sessions go on (they are not ours).
  void Shutdown() override;
  // For a scrape (server/ops/metrics.h): this replica's placement decisions, and the site's
  // registry as the store holds it (nodes by state; per node its sessions, capacity, epoch and
  // the age of its last heartbeat, i.e. of its lease). Reads the registry: any thread.
  void Collect(ops::MetricsText& out) const;

  struct Impl;

 private:
  explicit ClusterSessions(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct NodeOptions {
  static constexpr Range kCapacity{1, 4096};
  // --capacity's own: kDeriveCapacity (0, its default) asks for what the node's cores hold at its
  // scenes' cost (node_cost.h).
  static constexpr int kDeriveCapacity = 0;
  static constexpr Range kCapacityOption{kDeriveCapacity, kCapacity.hi};
  std::string name;       // unique in the site
  std::string advertise;  // host:port the control plane reaches NodeService at
  std::string control;    // the control plane's internal API: host:port[,host:port…]
  std::string udp_host;   // what stations are told to send to
  int udp_port = 0;
  int capacity = 24;  // live sessions this node takes
  // How capacity was reached: "set" (--capacity), or the cost it was derived from (node_cost.h).
  std::string capacity_from = "set";
  // On Drain, hand the live sessions to other nodes (live migration) before waiting for the
  // rest to finish; false: wait for all of them (--drain-wait).
  bool migrate_on_drain = true;
  ClusterOptions cluster;  // token, listen, heartbeat period, lease margin
  // The lease this agent acquires and renews; the node's endpoint and session manager read it.
  // Required; must outlive the agent.
  Lease* lease = nullptr;
};

class NodeAgent {
 public:
  static Expected<std::unique_ptr<NodeAgent>> Start(SessionManager& sessions,
                                                    const NodeOptions& options);
  ~NodeAgent();  // Shutdown()
  int port() const;
  int health_port() const;  // the plaintext health check's (0: none)
  // No new sessions from now on (the heartbeat says so at once); then (migrate_on_drain) each
  // live session is handed to another node through the control plane (ClusterService.Migrate:
  // its station fades for the move and follows it, server/session/session_manager.h
  // BeginMove); returns when the sessions no node took have finished or `timeout_s` passed (they
  // are then left to the shutdown, which aborts them). Returns how many moved.
  int Drain(double timeout_s);
  void Shutdown();
  // For a scrape: the lease as this node holds it (held, epoch, seconds left on its own clock),
  // draining, and the heartbeats refused or unanswered. Any thread.
  void Collect(ops::MetricsText& out) const;

  struct Impl;

 private:
  explicit NodeAgent(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::server::cluster
