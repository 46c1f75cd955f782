// The server's sessions: one Simulation per session, registered with the UDP endpoint while it
// runs, recorded in the store. The control plane (gRPC) calls this; it never sees a socket.
//
// Life cycle (DESIGN.md "Network"; STYLE.md: the SQLite way of documenting a state machine)
//
//   created ──Start──▶ running ◀──stylus again──▶ stalled      (endpoint events)
//      │                  │                          │
//      │                Stop                  no stylus 5 s
//      │                  ▼                          ▼
//      └──────Stop────▶ ended                  disconnected
//   any live state ──server shutdown──▶ aborted
//
//  transition                        function
//  ─────────────────────────────     ───────────────────────────────
//  (none) → created                  Create     (scene built, key issued, row written)
//  created → running                 Start      (added to the endpoint; stylus accepted)
//  running ⇄ stalled, → disconnected Pump       (the endpoint's events, every tick)
//  created → aborted                 Pump       (not started within start_timeout_s)
//  live → ended                      Stop       (removed from the endpoint, metrics recorded)
//  live → aborted                    Shutdown, EndSessionsOf (the user lost access)
//  live → (dropped, not written)     AbandonAll (a node's lease lost: the site aborted them)
//  live → moving → (gone, not written) BeginMove, FinishMove (live migration: another node
//                                    adopted it, and the store's row says so)
//  moving → live                     CancelMove (no node took it: it serves here again)
//  (none) → live, as it was          Adopt (a session moved from another node)
//
// Invariants
//  1. A session is in the endpoint exactly while it is running or stalled.
//  2. Every state change is written to the store before the call that made it returns (Pump
//     writes asynchronously; its order is kept by the single writer), under the session's
//     epoch: the store refuses the writes of a node that lost its lease (store.h note 7). A
//     write Pump could not make while the store was unavailable is made at the next ticks.
//  3. A session's trial metrics are recorded once, when it leaves the live states.
//  4. The Simulation outlives its registration with the endpoint (RemoveSession waits).
//  5. A session's deformation thread runs only while a station drives it (running, with stylus
//     samples); created and stalled sessions cost memory, bounded by the limits, and no CPU.
//  6. A trainee has at most max_sessions_per_user live sessions; the server at most
//     max_live_sessions. A session never started expires; one started and never driven is
//     disconnected by the endpoint (no stylus for 5 s).
//  7. A moving session is out of the endpoint (its station's datagrams go unanswered; the
//     station fades) and its simulation stands still; it is neither ended nor pumped, and a Stop
//     meanwhile is refused (kUnavailable: the control plane's next try reaches its new node).
//
// Threads: Create/Start/Stop/Get/List from any thread (gRPC); one sampler thread runs Pump and
// Sample at the telemetry rate and is the only reader of each simulation's telemetry.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/core/clock.h"
#include "common/core/expected.h"
#include "common/core/log.h"
#include "common/core/range.h"
#include "common/sim/case_bank.h"
#include "common/sim/simulation.h"
#include "db/store.h"
#include "proto/wire/datagram.h"
#include "server/net/lease.h"
#include "server/net/udp_endpoint.h"
#include "server/session/sessions.h"
#include "server/session/trace_recorder.h"

namespace vsurg::server {

// A live session on its way from one node to another (live migration; server/cluster/): what the
// receiving node needs to serve it on from where it was, sent as bytes (Bytes, FromBytes).
struct SessionHandoff {
  int64_t id = 0;
  std::string trainee, scene;
  SessionState state = SessionState::kCreated;  // a live state
  int64_t created_us = 0, started_us = 0;
  std::string key;  // the station's session key, 32 bytes
  scoring::TaskSettings task;
  std::optional<uint64_t> case_seed;  // a palpation's case (sim::DrawCase), redrawn by the receiver
  std::string simulation;             // sim::Simulation::SaveState
  std::string trace;                  // the TraceRecorder's state
  // The link so far (LinkStats): datagrams applied and lost, the span they came over (s), the
  // station's last round trip and jitter (µs) and its rendered peak and time over the limit.
  uint64_t applied = 0, lost = 0;
  double span_s = 0, rtt_us = 0, jitter_us = 0, rendered_peak_n = 0, rendered_over_limit_s = 0;
  std::string from_node;
  int64_t from_epoch = 0;

  std::string Bytes() const;
  static Expected<SessionHandoff> FromBytes(std::string_view bytes);
};

struct SessionManagerOptions {
  // The bounds Open checks (and vsurg-server's options show).
  static constexpr Range kTelemetryHz{1, 1000}, kMaxLiveSessions{1, 65536},
      kStartTimeoutS{0.1, 86400}, kDeformationWorkers{-1, 256}, kQuasiStaticIntervalS{0, 0.1};
  std::string udp_host = "127.0.0.1";  // what stations are told to send to
  // ... and at which port (0: the endpoint's own). A relay or a NAT in front of the endpoint
  // (bench/relay: network impairment) listens on another port than the endpoint's.
  uint16_t udp_port = 0;
  double telemetry_hz = 30;
  int max_live_sessions = 256;
  int max_sessions_per_user = 2;  // live sessions per trainee (a reconnect may overlap one)
  double start_timeout_s = 60;    // a created session not started by then is aborted
  // Start timeouts and haptic rates are measured on this clock (null: the steady clock); it must
  // outlive the manager. The sampler itself runs at telemetry_hz of real time.
  const Clock* clock = nullptr;
  // The simulation node this manager runs in (its sessions' rows say so); "" in the all-in-one
  // server, which aborts the sessions a previous process left live when it starts. A node does
  // not: its leftovers are aborted when it acquires its name (store.h design note 7).
  std::string node;
  // A node's lease (server/net/lease.h; its agent holds it): sessions are created only while it
  // is valid, and every store write carries the epoch a session was created under. Null in the
  // all-in-one server. Must outlive the manager.
  const Lease* lease = nullptr;
  // Driven sessions deform on a pool of this many workers (common/sim/deformation_pool.h; 0:
  // one per core), or −1 (the default) each on a thread of its own. The pool is not the default
  // yet: at 64 stations on 2 cores it did not lower the haptic round trip's p99 (BENCHMARKS.md,
  // "A deformation pool instead of a thread per session").
  int deformation_workers = -1;
  // A quasi-static model's updates while a hand twists: at most one per this many seconds
  // (sim::SimulationOptions::quasi_static_interval_s; 0: every request). Within [0, 0.1].
  double quasi_static_interval_s = sim::kQuasiStaticIntervalS;
  // Palpation cases kept built ahead for each scene that draws them (sim::CaseBank), so that a
  // trainee's session starts without waiting for its case's table; 0: each session builds its own
  // when it is created (tests). vsurg-server keeps 2.
  static constexpr Range kCasesReady{0, 16};
  int cases_ready = 0;
};

class SessionManager final : public Sessions {
 public:
  // Settings → object, validated once (a field that is out of range is kInvalidArgument, naming
  // it); then the all-in-one server's leftovers are aborted (a store that cannot be written is
  // an error here, not a silent start) and the sampler starts. `endpoint` may be null (a control
  // plane without a haptic channel: sessions cannot start).
  static Expected<std::unique_ptr<SessionManager>> Open(db::Store& store, UdpEndpoint* endpoint,
                                                        const SessionManagerOptions& options);
  ~SessionManager();  // Shutdown()
  SessionManager(const SessionManager&) = delete;
  SessionManager& operator=(const SessionManager&) = delete;

  Expected<CreatedSession> Create(const std::string& trainee, const std::string& scene,
                                  const scoring::TaskSettings& task = {}) override;
  // The same on a simulation node, for a placement a control replica reserved on it
  // (db::Store::ReservePlacement): the session's row replaces the reservation.
  Expected<CreatedSession> Create(const std::string& trainee, const std::string& scene,
                                  const scoring::TaskSettings& task, const std::string& placement);
  Expected<db::SessionRecord> Start(uint64_t id) override;
  Expected<db::SessionRecord> Stop(uint64_t id, const std::string& reason) override;
  // A session whose creator stopped waiting before it was answered (server/cluster/: a Create
  // that outlived its caller): aborted with `reason` at once if it has never been started;
  // FAILED_PRECONDITION once it has (someone holds its key after all), NOT_FOUND when gone.
  Expected<db::SessionRecord> Abandon(uint64_t id, const std::string& reason);
  Expected<db::SessionRecord> Get(uint64_t id) override;
  Expected<CreatedSession> Join(uint64_t id, bool with_surface) override;
  // Four-handed training (sessions.h; session_guidance.cpp).
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
  // Live sessions now (a simulation node's load report), and their ids.
  int LiveCount() const;
  std::vector<uint64_t> LiveIds() const;
  // The node lost its lease (the control plane declared it down, or a newer process took its
  // name): every live session is dropped here, without a store write (the store refuses them;
  // the control plane has aborted those sessions already) and without trial metrics. Returns
  // how many were dropped. Any thread.
  int AbandonAll(const std::string& reason);

  // Live migration (a draining node's sessions to other nodes; server/cluster/node_agent.cpp).
  // BeginMove takes a live session out of service here and returns its state (invariant 7);
  // then exactly one of FinishMove (another node adopted it: it is forgotten here, unwritten)
  // or CancelMove (no answer said so: it serves here again, unless the store's row names another
  // node now or the session has ended, when it is forgotten as by FinishMove; a store that does
  // not answer leaves it here). kNotFound: not live here; kFailedPrecondition: moving already.
  Expected<SessionHandoff> BeginMove(uint64_t id);
  // The palpation cases kept ahead (SessionManagerOptions::cases_ready).
  const sim::CaseBank& cases() const { return *cases_; }
  void FinishMove(uint64_t id);
  void CancelMove(uint64_t id);
  // A session moved here from another node: its simulation built and set to the handoff's state,
  // the store's row made this node's (Store::MoveSession, fenced by both nodes' epochs), then
  // served in the state it had (a started one in the endpoint, under the same key). Refused
  // without a lease, at max_live_sessions, or when the state is not one this server reads.
  // Nothing is committed after `deadline` (the control plane's for the call: past it the
  // sender may have taken the session back).
  // `placement`: the reservation the control replica made for the move, which the row replaces.
  Expected<CreatedSession> Adopt(
      const SessionHandoff& handoff,
      std::chrono::system_clock::time_point deadline = std::chrono::system_clock::time_point::max(),
      const std::string& placement = "");

  // Aborts every live session (metrics recorded), stops the sampler. Idempotent.
  void Shutdown() override;

 private:
  struct Live {
    std::unique_ptr<sim::Simulation> simulation;
    LinkStats link;
    wire::SessionKey key{};
    SessionState state = SessionState::kCreated;  // a live state
    db::SessionRecord record;
    SessionTelemetry latest;
    uint64_t rate_samples = 0;          // the rate window's start: samples applied by then,
    double rate_time = -1;              // and the station's clock (s); −1: none yet
    double created_s = 0;               // clock_, for start_timeout_s
    int64_t epoch = 0;                  // the lease's when created: every store write carries it
    TraceRecorder trace;                // the session's record (sampler thread, under mutex_)
    scoring::TaskSettings task;         // the settings the session was created with
    std::optional<uint64_t> case_seed;  // a palpation's case (sim::DrawCase)
    bool moving = false;                // BeginMove .. FinishMove or CancelMove (invariant 7)
    // Four-handed training: the instructor on the tool's second channel ("" none), its key
    // and link (the channel is in the endpoint while `instructor` is set).
    std::string instructor;
    wire::SessionKey instructor_key{};
    LinkStats instructor_link;
    // Two hands: the station's second device's channel (SecondHandChannel), its key and link;
    // in the endpoint from Start on.
    bool two_hands = false;
    wire::SessionKey second_key{};
    LinkStats second_link;
  };
  void KeepCases();
  // The live session `id` (under mutex_), or kNotFound / kUnavailable (moving).
  Expected<Live*> LiveSession(uint64_t id) const;
  // Closes the instructor's channel of a live session taken out of service (no lock needed:
  // the caller owns `l`, or holds mutex_).
  void CloseInstructor(uint64_t id, Live& l);
  // Takes a started session's station channels (both hands') out of the endpoint.
  void RemoveChannels(uint64_t id, const Live& l);
  // The scene by name with the task settings applied, its simulation built (not driven). A scene
  // that draws palpation cases takes `case_seed`'s case, or else a ready one from the bank (a new
  // one when none is ready), and says which in `case_seed`.
  Expected<std::unique_ptr<sim::Simulation>> BuildSimulation(const std::string& scene_name,
                                                             const scoring::TaskSettings& task,
                                                             std::optional<uint64_t>& case_seed);
  SessionManager(db::Store& store, UdpEndpoint* endpoint, const SessionManagerOptions& options);
  // `retry`: the sampler's own ends (Pump), whose write is kept and made again while the store is
  // unavailable (sampler thread only).
  // `unstarted_only`: FAILED_PRECONDITION, and nothing ended, when the session has been started.
  Status End(uint64_t id, SessionState state, const std::string& reason, bool retry = false,
             bool unstarted_only = false);
  // A state change the sampler could not write (invariant 2): kept and written again at the next
  // ticks while the store is unavailable; any other refusal (the node's lease is lost, the
  // session ended elsewhere) is final and logged. Sampler thread only.
  struct PendingWrite {
    int64_t id = 0;
    SessionState state = SessionState::kRunning;
    int64_t at_us = 0;
    std::string reason;
    std::optional<scoring::TrialMetrics> metrics;  // an end's trial
    int64_t epoch = 0;
    std::string trace;  // an end's record (TraceRecorder::Json), "" when nothing was driven
  };
  Status Write(const PendingWrite& w);
  // One event line about a session (common/core/log.h): its id first, this node's name last.
  void Log(const char* event, int64_t session, LogFields fields = {}) const;
  void WriteOrKeep(PendingWrite w);  // sampler thread
  void RetryPending();               // sampler thread
  void NotifyEnded(uint64_t id);     // subscribers of `id` hear that it ended
  uint16_t AdvertisedUdpPort()
      const;  // what stations are told to send to (options or the endpoint's)
  Status CheckLimits(const std::string& trainee) const;
  Status CheckLimitsLocked(const std::string& trainee) const;  // mutex_ held
  void SamplerLoop();
  void Pump();
  static void UpdateHapticRate(Live& l, SessionTelemetry& t);  // sampler thread

  db::Store& store_;
  UdpEndpoint* endpoint_;
  SessionManagerOptions options_;
  const Clock& clock_;
  // Before live_: the sessions' simulations leave the pool before it stops.
  std::unique_ptr<sim::DeformationPool> pool_;
  std::unique_ptr<sim::CaseBank> cases_;  // palpation cases ahead (options_.cases_ready)
  mutable std::mutex mutex_;              // live_
  std::map<uint64_t, std::unique_ptr<Live>> live_;
  std::mutex subscribers_mutex_;  // held while subscribers run (see Unsubscribe)
  std::map<uint64_t, std::pair<uint64_t, Subscriber>> subscribers_;
  uint64_t next_token_ = 1;
  std::vector<PendingWrite> pending_;  // sampler thread; at most kMaxPending
  static constexpr size_t kMaxPending = 4096;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  std::thread sampler_;
};

}  // namespace vsurg::server
