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
//
// Invariants
//  1. A session is in the endpoint exactly while it is running or stalled.
//  2. Every state change is written to the store before the call that made it returns (Pump
//     writes asynchronously; its order is kept by the single writer).
//  3. A session's trial metrics are recorded once, when it leaves the live states.
//  4. The Simulation outlives its registration with the endpoint (RemoveSession waits).
//  5. A session's deformation thread runs only while a station drives it (running, with stylus
//     samples); created and stalled sessions cost memory, bounded by the limits, and no CPU.
//  6. A trainee has at most max_sessions_per_user live sessions; the server at most
//     max_live_sessions. A session never started expires; one started and never driven is
//     disconnected by the endpoint (no stylus for 5 s).
//
// Threads: Create/Start/Stop/Get/List from any thread (gRPC); one sampler thread runs Pump and
// Sample at the telemetry rate and is the only reader of each simulation's telemetry.
#pragma once

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
#include "common/sim/simulation.h"
#include "db/store.h"
#include "proto/wire/datagram.h"
#include "server/net/udp_endpoint.h"

namespace vsurg::server {

struct SessionTelemetry {
  uint64_t id = 0;
  SessionState state = SessionState::kCreated;
  int64_t server_time_us = 0;
  sim::Telemetry sim;
  double rtt_us = 0;
  double packet_loss = 0;  // lost / (applied + lost)
  uint64_t packets = 0;
  // The station's haptic loop rate: stylus samples applied per second of the station's own clock
  // (the stamps it sends), over windows of ≥ 1 s, refreshed once a window; 0 unless running.
  double haptic_rate_hz = 0;
  std::string scene;
  std::string trainee;
  // Every third sample (10 Hz at the default rate): the deformed surface for monitors, as the
  // vertices away from rest (sim::Simulation::ShownSurface).
  bool has_surface = false;
  uint64_t surface_frame = 0;
  std::vector<int32_t> surface_indices;
  std::vector<geometry::Vec3> surface_positions;
};

struct CreatedSession {
  db::SessionRecord record;
  wire::SessionKey key{};
  std::string udp_host;
  uint16_t udp_port = 0;
};

struct SessionManagerOptions {
  std::string udp_host = "127.0.0.1";  // what stations are told to send to
  double telemetry_hz = 30;
  int max_live_sessions = 256;
  int max_sessions_per_user = 2;  // live sessions per trainee (a reconnect may overlap one)
  double start_timeout_s = 60;    // a created session not started by then is aborted
  // Start timeouts and haptic rates are measured on this clock (null: the steady clock); it must
  // outlive the manager. The sampler itself runs at telemetry_hz of real time.
  const Clock* clock = nullptr;
};

class SessionManager {
 public:
  // `endpoint` may be null (a control plane without a haptic channel: sessions cannot start).
  SessionManager(db::Store& store, UdpEndpoint* endpoint, const SessionManagerOptions& options);
  ~SessionManager();  // Shutdown()
  SessionManager(const SessionManager&) = delete;
  SessionManager& operator=(const SessionManager&) = delete;

  // `scene` is a scene name from scenes/ (letters, digits, '-'), never a path.
  Expected<CreatedSession> Create(const std::string& trainee, const std::string& scene);
  Expected<db::SessionRecord> Start(uint64_t id);
  Expected<db::SessionRecord> Stop(uint64_t id, const std::string& reason);
  Expected<db::SessionRecord> Get(uint64_t id);  // the store's row with the live state
  // A live session's station credentials (a session an instructor prepared, joined by the
  // trainee's station): the key and the UDP address, as Create returned them. kNotFound once it
  // left the live states.
  Expected<CreatedSession> Join(uint64_t id);
  // A live session's surface at rest (the mesh the monitors' surface states move): positions in
  // metres, triangles as vertex indices. kNotFound once it left the live states.
  Status RestSurface(uint64_t id, std::vector<geometry::Vec3>& positions,
                     std::vector<int32_t>& triangles) const;
  bool IsLive(uint64_t id) const;
  // Aborts every live session of `user` (its trainee), e.g. when their tokens are revoked or the
  // account is disabled: access ends with the account, on the UDP channel too. Returns how many.
  int EndSessionsOf(const std::string& user, const std::string& reason);

  // Telemetry subscribers: `fn` runs on the sampler thread at the telemetry rate with the
  // latest figures of every live session (or of `session` only, when not 0), and once more with
  // an empty list when that session leaves the live states. Unsubscribe waits for a running
  // call to finish, so after it returns `fn` is never called again.
  using Subscriber = std::function<void(const std::vector<SessionTelemetry>&, bool ended)>;
  uint64_t Subscribe(uint64_t session, Subscriber fn);
  void Unsubscribe(uint64_t token);

  // Aborts every live session (metrics recorded), stops the sampler. Idempotent.
  void Shutdown();

 private:
  struct Live {
    std::unique_ptr<sim::Simulation> simulation;
    LinkStats link;
    wire::SessionKey key{};
    SessionState state = SessionState::kCreated;  // a live state
    db::SessionRecord record;
    SessionTelemetry latest;
    uint64_t rate_samples = 0;  // the rate window's start: samples applied by then,
    double rate_time = -1;      // and the station's clock (s); −1: none yet
    double created_s = 0;       // clock_, for start_timeout_s
  };
  Status End(uint64_t id, SessionState state, const std::string& reason);
  Status CheckLimits(const std::string& trainee) const;
  Status CheckLimitsLocked(const std::string& trainee) const;  // mutex_ held
  void SamplerLoop();
  void Pump();
  static void UpdateHapticRate(Live& l, SessionTelemetry& t);  // sampler thread

  db::Store& store_;
  UdpEndpoint* endpoint_;
  SessionManagerOptions options_;
  const Clock& clock_;
  mutable std::mutex mutex_;  // live_
  std::map<uint64_t, std::unique_ptr<Live>> live_;
  std::mutex subscribers_mutex_;  // held while subscribers run (see Unsubscribe)
  std::map<uint64_t, std::pair<uint64_t, Subscriber>> subscribers_;
  uint64_t next_token_ = 1;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  std::thread sampler_;
};

}  // namespace vsurg::server
