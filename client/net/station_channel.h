// The station side of the UDP haptic channel (DESIGN.md "Haptic interaction", "Network").
//
// Two threads:
//   device thread, at rate_hz (1 kHz): read the device; send a StylusState datagram; render the
//     force from the latest local model, F = F₀ + J·(x − x₀), whatever the network is doing;
//     watchdog (no server update for watchdog_s → the force fades linearly to zero over fade_s);
//     passivity observer and controller (Hannaford & Ryu 2002: the energy the rendered force has
//     put into the hand; when the coupling has generated energy, a damping that dissipates it);
//     the station's own safety filter (device limits, start-up gate, ramp-in, rate limit);
//     write the force.
//   network thread: receive ForceFeedback datagrams, authenticate, drop stale ones (latest
//     wins), hand the newest to the device thread through a lock-free triple buffer, and
//     measure the round trip from the echoed send time; queue SceneFrame chunks for rendering.
// UDP needs no connection: when the server comes back the station's next datagrams are answered
// again (the force was faded meanwhile), which is all a reconnect is here.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "client/device/device.h"
#include "common/core/clock.h"
#include "common/core/expected.h"
#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"

namespace vsurg::client {

struct StationOptions {
  std::string server_address = "127.0.0.1";
  uint16_t server_port = 0;
  uint64_t session = 0;
  wire::SessionKey key{};
  double rate_hz = 1000;
  double watchdog_s = 0.020;  // no update for this long: start fading
  double fade_s = 0.050;      // from full force to zero
  bool passivity = true;
  int realtime_priority = 0;  // > 0: SCHED_FIFO at this priority for both threads, if permitted
  double max_damping = 5.0;   // N·s/m the passivity controller may add
  // The station clock (sample times, round trips, the watchdog and its fade); null: the steady
  // clock. The device loop itself is paced by real time at rate_hz whatever this clock says.
  const Clock* clock = nullptr;
};

struct StationStats {
  uint64_t sent = 0, received = 0, dropped = 0, stale = 0;
  double rtt_p50_us = 0, rtt_p99_us = 0, rtt_p999_us = 0;
  double jitter_us = 0;                    // mean |RTT_i − RTT_{i−1}|
  double loss = 0;                         // 1 − received / sent
  uint64_t watchdog_fades = 0;             // times the watchdog started fading
  uint64_t scene_chunks = 0;               // SceneFrame datagrams received
  double passivity_energy_dissipated = 0;  // J the controller removed
  double max_force = 0;                    // N rendered
  // The device loop, paced by real time at rate_hz: iterations over its running time, and the
  // slowest and fastest whole second (0 before the first second ends).
  uint64_t loop_iterations = 0;
  double loop_seconds = 0;
  double loop_hz = 0;  // loop_iterations / loop_seconds
  double loop_hz_min = 0, loop_hz_max = 0;
};

// What the station's screen shows of the haptic loop (device thread → render thread).
struct StationView {
  haptics::StylusSample sample;                     // the device, as last read (station clock)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N, as last written to the device
  haptics::ForceCommand command;  // the server's latest answer (twist, contact, live score)
  double update_age_s = -1;       // since that answer arrived; −1: none yet
};

class StationChannel {
 public:
  static Expected<std::unique_ptr<StationChannel>> Create(const StationOptions& options,
                                                          HapticDevice* device);
  ~StationChannel();  // stops and joins

  // Stops both threads and writes a zero force to the device (idempotent).
  void Stop();
  // Any thread. Copies the round-trip ring (65 536 samples) and selects its percentiles:
  // about a millisecond, so call it for a report, not every frame.
  StationStats stats() const;
  uint64_t received() const;  // any thread: force updates received (one atomic load)
  // Render thread: the scene chunks received since the previous call (moved vertices, m).
  // At most 4096 are kept between calls; older ones are dropped first.
  std::vector<wire::SceneChunk> TakeSceneChunks();
  Eigen::Vector3d last_force() const;
  // Render thread (one reader): the device thread's latest view; false when nothing new.
  bool TakeView(StationView& out);

 private:
  struct Impl;
  explicit StationChannel(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::client
