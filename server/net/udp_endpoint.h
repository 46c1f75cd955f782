// The server's UDP haptic endpoint (DESIGN.md "Network", STYLE.md: the domain handler never sees
// a socket).
//
// One I/O thread per lane (EndpointOptions::io_threads, 1 by default) owns its socket and its
// share of the session table; it blocks in recvmmsg on its socket (no event loop: a lone datagram
// costs its receive and its answer's send, two system calls, as a bare echo's; under load one
// receive takes up to 16). With several lanes the sockets share the port (SO_REUSEPORT) and the
// kernel steers each datagram to its session's lane by the session id (a classic BPF program on
// the port's group), so each session has one thread and the hot path takes no lock.
//
// Per datagram: framing and size checks, the session's key, the tag, latest-wins (a sequence not
// newer than the last applied is stale: reordered or replayed), a per-session rate limit, the
// payload; then Simulation::OnStylus and a ForceFeedback datagram back to the sender at once.
// Anything that fails is dropped and counted by reason; nothing unauthenticated is ever answered.
//
// Two more checks before a force is computed: the datagram's age in the receive queue (the
// kernel's arrival stamp, SO_TIMESTAMPNS; older than max_input_age_s: dropped as late) and, on a
// simulation node, the node's lease (lapsed: dropped as fenced, so a node the site gave up on
// never answers its old stations).
//
// Session life cycle (checked every 50 ms: a quiet socket's receive times out then):
//
//   added ──stylus──▶ running ──no stylus 0.5 s──▶ stalled ──no stylus 5 s──▶ disconnected
//                        ▲                            │                          │
//                        └────────stylus again────────┴──────────────────────────┘
//
// A session that moved to another node (NoticeMoved) stays in the table for a while without a
// simulation: its datagrams get a "moved" notice instead of a force, and it records no events.
//
// Transitions are recorded as events for the control plane (TakeEvents). Sessions are added and
// removed on their lane's I/O thread (queued, the thread woken by a datagram from the endpoint's
// own waker socket, steered to that lane), so the hot path takes no lock.
//
// Visual frames: a VisualSender (server/net/visual_sender.h), with its own thread and socket so it
// never delays a force, sends each session's moved vertices as SceneFrame datagrams at visual_hz
// to the address the session's stylus data last came from.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/core/clock.h"
#include "common/core/expected.h"
#include "common/core/range.h"
#include "common/core/session_state.h"
#include "proto/wire/datagram.h"

namespace vsurg::sim {
class Simulation;
}

namespace vsurg::server {

class Lease;

struct EndpointOptions {
  // The bounds Create checks (and vsurg-server's options show).
  static constexpr Range kPort{0, 65535}, kRealtimePriority{0, 99}, kIoThreads{1, 16},
      kBusyPollUs{0, 10000};
  std::string address = "127.0.0.1";  // loopback unless configured otherwise
  uint16_t port = 0;                  // 0: an ephemeral port (see port())
  double stall_after_s = 0.5;
  double disconnect_after_s = 5.0;
  double max_packets_per_s = 4000;  // per session; a 1 kHz station never comes near
  double visual_hz = 60;            // scene frames per second (0: none)
  int realtime_priority = 0;        // > 0: SCHED_FIFO for the I/O threads, when permitted
  // I/O threads (lanes), each with its own socket on the port; sessions are spread over them by
  // id. 1: one socket, no SO_REUSEPORT. More: the port is held by this endpoint alone (a second
  // endpoint on it is refused, as with one lane).
  int io_threads = 1;
  // Busy polling: before a lane blocks for its next datagram it polls its socket for up to this
  // long (µs), but only while its datagrams came faster than one per window over the last
  // housekeeping tick (50 ms). A thread woken from sleep pays the scheduler's wake-up, and on a
  // virtual machine whose idle cores halt to the hypervisor an exit and re-entry too; under load
  // the poll keeps the lane awake between datagrams instead. A lane with few stations never
  // polls, so an idle or lightly loaded node burns nothing. 0: off (always block), the default:
  // on this machine kind, with the stations and the deformation threads on the same two cores,
  // polling lowered the median round trip but not reliably the p99 (docs/BENCHMARKS.md, "Busy
  // polling while the datagrams come fast"); it is for a node whose cores are its own.
  int busy_poll_us = 0;
  // The socket's receive buffer (SO_RCVBUF, capped by the kernel's net.core.rmem_max): what a
  // burst of datagrams may queue while the I/O thread is kept off a core, instead of being
  // dropped. 1 MiB: about 15 ms of 64 stations at 1 kHz. 0: the kernel's default (~208 KiB).
  int receive_buffer_bytes = 1 << 20;
  // The endpoint's clock (timeouts, the rate limit, server_time); null: the steady clock. Must
  // outlive the endpoint.
  const Clock* clock = nullptr;
  // A stylus datagram that waited in this server's receive queue longer than this (the kernel's
  // arrival stamp against the time it is read: a process that was frozen, or starved of a core)
  // is dropped, never answered: its force would act on where the hand was, not where it is (the
  // station meanwhile renders its last local model, or has faded a bare force within 70 ms). A
  // server only descheduled for a moment on a loaded machine still answers; a frozen one never
  // does.
  double max_input_age_s = 0.25;
  // A simulation node's lease (server/net/lease.h): while it is not valid no force is sent for
  // any session. Null: the all-in-one server, which needs none. Must outlive the endpoint.
  const Lease* lease = nullptr;
};

struct EndpointCounters {
  uint64_t received = 0;
  uint64_t answered = 0;
  uint64_t frames = 0;        // visual frames sent
  uint64_t frame_chunks = 0;  // their datagrams
  uint64_t frame_bytes = 0;   // and those datagrams' bytes
  uint64_t busy_polls = 0;    // times an I/O thread polled before it slept (busy_poll_us)
  uint64_t busy_polled = 0;   // of which found datagrams (the rest ended in a sleep)
  std::array<uint64_t, static_cast<size_t>(wire::DropReason::kCount)> dropped{};
  uint64_t Dropped(wire::DropReason r) const { return dropped[static_cast<size_t>(r)]; }
  // Each answer's residence: from the stylus datagram's arrival (the kernel's stamp) to its
  // answer's send returning, the node's own share of the round trip (its queue, the physics and
  // the send). Bucket b holds the answers at most kResidenceBounds[b] and above the bound before
  // it; the last, above all.
  static constexpr std::array<double, 14> kResidenceBounds{10e-6,  20e-6,  35e-6,  50e-6,  75e-6,
                                                           100e-6, 150e-6, 250e-6, 500e-6, 1e-3,
                                                           2e-3,   5e-3,   10e-3,  20e-3};
  std::array<uint64_t, kResidenceBounds.size() + 1> residence_buckets{};
  double residence_seconds = 0;  // their sum
  // The residence below which a fraction q of the answers fell, as the bucket's upper bound
  // (+inf in the last); 0 with no answers.
  double ResidenceQuantile(double q) const;
};

// A session's link figures for the control plane's telemetry. Owned by the caller of AddSession,
// written by the I/O thread only (relaxed atomics: each figure is independent), read by any.
struct LinkStats {
  std::atomic<uint64_t> applied{0};      // stylus datagrams applied
  std::atomic<uint64_t> lost{0};         // sequence numbers skipped (lost or still in flight)
  std::atomic<double> rtt_us{0};         // the station's last reported round trip
  std::atomic<double> last_seen_s{0};    // endpoint clock, s
  std::atomic<double> first_seen_s{-1};  // endpoint clock, s; −1: nothing applied yet
  // The station's own account of what it rendered, and its jitter (StylusMessage); 0: none.
  std::atomic<double> rendered_peak_n{0}, rendered_over_limit_s{0}, jitter_us{0};
  // Seconds of the trial served by the nodes before this one (live migration): the rate is
  // applied datagrams over this span plus this node's.
  std::atomic<double> carried_s{0};

  // Seconds the session's datagrams came over: on this node, and on the nodes before (a move).
  double span_s() const {
    const auto relaxed = std::memory_order_relaxed;
    const double here = first_seen_s.load(relaxed) >= 0
                            ? last_seen_s.load(relaxed) - first_seen_s.load(relaxed)
                            : 0;
    return here + carried_s.load(relaxed);
  }
};

struct SessionEvent {
  uint64_t session = 0;
  SessionState state = SessionState::kRunning;  // running, stalled or disconnected
  double at_s = 0;                              // seconds since the endpoint started
};

// Four-handed training: the wire id of an instructor's channel into session `session`. Its low
// byte is the session's, so the port's steering gives it the session's lane (one thread for both
// hands); the slot sits in the top byte, above any session id the store hands out.
inline constexpr uint64_t kChannelSlotShift = 56;
constexpr uint64_t InstructorChannel(uint64_t session, uint64_t slot = 1) {
  return session | (slot << kChannelSlotShift);
}
// Two hands: the wire id of a station's second device's channel into its own session (the same
// lane, the slot after the instructor's).
constexpr uint64_t SecondHandChannel(uint64_t session) {
  return InstructorChannel(session, 2);
}

// Who sends on a channel into a session: its trainee's station (the session's own id), an
// instructor's (Simulation::OnInstructorStylus) or the trainee's second device
// (Simulation::OnSecondHandStylus).
enum class ChannelRole { kTrainee, kInstructor, kSecondHand };

class UdpEndpoint {
 public:
  static Expected<std::unique_ptr<UdpEndpoint>> Create(const EndpointOptions& options);
  ~UdpEndpoint();  // stops and joins

  static constexpr int kMaxIoThreads = static_cast<int>(EndpointOptions::kIoThreads.hi);
  static constexpr int kMaxBusyPollUs = static_cast<int>(EndpointOptions::kBusyPollUs.hi);

  uint16_t port() const;
  int io_threads() const;
  // The lane (0 .. io_threads−1) that serves session `id`.
  int LaneOf(uint64_t id) const;
  // The socket's receive buffer as the kernel keeps it (bytes; Linux reports twice what was
  // granted: its bookkeeping's share included).
  int receive_buffer_bytes() const;
  // Any thread. The simulation (and `link`, when given) must outlive the session's removal
  // (RemoveSession waits for it).
  void AddSession(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation,
                  LinkStats* link = nullptr);
  // A second channel into a live session: an instructor's (four-handed training,
  // InstructorChannel's id) or the trainee's second device's (SecondHandChannel's), so it shares
  // the session's lane and thread; its datagrams are answered by the role's haptic path. It
  // records no session events (its silence is the simulation's to handle) and gets no visual
  // frames. Removed by RemoveSession(channel).
  void AddChannel(uint64_t channel, ChannelRole role, const wire::SessionKey& key,
                  sim::Simulation* simulation, LinkStats* link = nullptr);
  void AddInstructorChannel(uint64_t channel, const wire::SessionKey& key,
                            sim::Simulation* simulation, LinkStats* link = nullptr) {
    AddChannel(channel, ChannelRole::kInstructor, key, simulation, link);
  }
  void RemoveSession(uint64_t id);
  // The session has moved to another node (live migration) and is no longer here: for
  // `for_s` seconds its station's datagrams (authenticated with `key`, within the rate limit)
  // are answered with a notice (zero force, haptics::kEventSessionMoved, computed by nothing)
  // so that it asks where the session runs at once instead of after its silence timeout.
  void NoticeMoved(uint64_t id, const wire::SessionKey& key, double for_s = 10);
  void Stop();

  EndpointCounters counters() const;          // any thread; every lane's
  EndpointCounters counters(int lane) const;  // one lane's (no visual frames)
  // CPU time the I/O threads have used together (s), sampled every 50 ms.
  double io_cpu_seconds() const;
  // A lane's I/O thread (the stylus → force path), for diagnostics and the allocation test.
  std::thread::id io_thread_id(int lane = 0) const;
  std::vector<SessionEvent> TakeEvents();
  // Runs the stall/disconnect check now, on the I/O thread, and waits for it (it also runs every
  // 50 ms of real time): with a ManualClock, a test advances the clock and calls this.
  void CheckTimeoutsNow();
  // Runs `fn` on a lane's I/O thread and waits for it: a test holds the thread as a frozen or
  // starved process would (the age bound), a diagnostic reads its state.
  void RunOnIoThread(std::function<void()> fn, int lane = 0);

 private:
  struct Impl;
  explicit UdpEndpoint(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::server
