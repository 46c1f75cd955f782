// The station side of the UDP haptic channel (DESIGN.md "Haptic interaction", "Network").
//
// Two threads:
//   device thread, at rate_hz (1 kHz): read the device; send a StylusState datagram; render the
//     force from the latest local model, F = F₀ + J·(x − x₀), whatever the network is doing;
//     watchdog (no server update for watchdog_s → the force fades linearly to zero over fade_s;
//     a contact's or grasp's local model is first held for model_hold_s);
//     passivity observer and controller (Hannaford & Ryu 2002: the energy the rendered force has
//     put into the hand; when the coupling has generated energy, a damping that dissipates it);
//     the station's own safety filter (device limits, start-up gate, ramp-in, rate limit);
//     write the force.
//   network thread: receive ForceFeedback datagrams, authenticate, drop stale ones (latest
//     wins), hand the newest to the device thread through a lock-free triple buffer, and
//     measure the round trip from the echoed send time; queue SceneFrame chunks for rendering.
// UDP needs no connection: when the server comes back the station's next datagrams are answered
// again (the force was held or faded meanwhile), which is all a reconnect is here. Stop fades the
// force out over fade_s (in servo cycles) before it returns: a stop never cuts a held force.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "client/device/device.h"
#include "client/net/passivity.h"
#include "common/core/clock.h"
#include "common/core/expected.h"
#include "common/haptics/blade.h"
#include "common/haptics/needle_contact.h"
#include "common/haptics/tissue_surface.h"
#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"

namespace vsurg::client {

// What the device thread renders between the server's answers (docs/BENCHMARKS.md compares
// them side by side across network profiles):
//   kServerForce  the latest answer's force, held (no local model);
//   kLinear       F₀ + J·(x − x₀) everywhere while the answer is in contact or grasping,
//                 whatever its kind, and nothing ahead of contact (the first linear model);
//   kModel        the answer's local model by its kind (haptics::LocalModel::Render): contact
//                 only on the surface's side, grasp only while the button is held, the twist's
//                 own stiffness; the surface ahead of contact.
enum class LocalRendering { kServerForce, kLinear, kModel };
Expected<LocalRendering> ParseLocalRendering(const std::string& name);  // server, linear, model
Expected<PassivityMode> ParsePassivityMode(const std::string& name);    // local, network

struct StationOptions {
  std::string server_address = "127.0.0.1";
  uint16_t server_port = 0;
  uint64_t session = 0;
  wire::SessionKey key{};
  double rate_hz = 1000;
  double watchdog_s = 0.020;  // no update for this long: start fading
  double fade_s = 0.050;      // from full force to zero
  // kModel: an answer whose local model is a contact's or a grasp's (a passive field about the
  // tissue's state: a surface's spring and damper, the grasp's hold spring and torque curve) is
  // rendered for this long without a newer one before the watchdog fades it. Model-mediated
  // teleoperation's premise (Mitra & Niemeyer 2008; held across 1 s round trips, Xu et al. 2014):
  // through a Wi-Fi roam the hand keeps feeling the tissue instead of falling into it, and is not
  // pushed back out when the answers return (a fade there gave the hand 3-6 mJ the tissue never
  // had; docs/BENCHMARKS.md). Release and leaving the surface stay local: the model ends them. A
  // server that is gone is found by the station's probe (station.h, silence_s), which stops the
  // channel, and Stop fades. 0: the watchdog alone, for every answer.
  double model_hold_s = 1.0;
  bool passivity = true;
  // kLocal: the one-port observer on the rendering; kNetwork: the two-port's station side,
  // which gives the hand no more energy than the server's answers say the tissue released
  // (client/net/passivity.h).
  PassivityMode passivity_mode = PassivityMode::kLocal;
  int realtime_priority = 0;  // > 0: SCHED_FIFO at this priority for both threads, if permitted
  double max_damping = 5.0;   // N·s/m the passivity controller may add
  LocalRendering rendering = LocalRendering::kModel;
  // A grasp rendered by the server's exact grasp force about each answer (the arc, the turning
  // tangent, the torque curve: haptics::LocalModel::has_twist_model); false renders its first
  // order (g·Δφ) as the stations before it did, for side-by-side comparisons.
  bool exact_grasp = true;
  // The perceptual deadband (station_channel.cpp, Deadband): 0 sends the stylus every cycle;
  // k > 0 sends it when the rendered force changed by more than k of itself (Weber fraction,
  // ≈ 0.1), the tip moved more than deadband_position_m or turned more than deadband_angle_rad,
  // the buttons changed, or heartbeat_s passed (deadband_contact_heartbeat_s while a force is
  // rendered). The server answers each sample, so its answers
  // thin alike; the watchdog then waits heartbeat_s + 35 ms before it fades.
  // A contact's first deadband_onset_s (from the cycle the rendered force appears) is sent
  // every cycle: an impact is where the tissue's answer changes fastest and the station knows
  // least of it (its tissue model is fitted from the contact itself).
  double deadband = 0;
  // The coil limb whose twist frames this station remakes (sim::CoilLimbKey), declared in every
  // stylus datagram; 0: it takes vertices.
  uint64_t twist_shape_key = 0;
  double deadband_position_m = 0.5e-3;
  double deadband_angle_rad = 0.0175;  // 1°
  double deadband_onset_s = 0.05;
  double heartbeat_s = 0.025;
  // The heartbeat while a force is rendered: the server's tissue is driven by the samples it
  // gets, so in contact they come more often (15 ms: the stiff sphere's force error at lan within
  // a point of the full rate, at 72 datagrams per second; 25 ms missed by 1.2 points; BENCHMARKS).
  double deadband_contact_heartbeat_s = 0.015;
  // The task's force limit (N): the station reports how long its rendered force was above it,
  // beside the largest it rendered, in every stylus datagram (the trial record keeps both).
  // 0: not counted.
  double force_limit_n = 0;
  // Non-empty: one CSV row per servo cycle, `t_s,x_m,y_m,z_m,fx_n,fy_n,fz_n` (station clock,
  // stylus position, the force sent to the device after every filter), written by a thread of
  // its own so the device loop never waits on the disk (rows that find the queue full are
  // counted in StationStats::force_log_dropped, never waited for).
  std::string force_log;
  // The tissue's surface at rest and its contact law, from the join (haptics/tissue_surface.h):
  // with kModel, a tip the server's answers still call free is given the surface ahead from the
  // station's own position, so a contact begins where and when the tip crosses the surface,
  // however long the round trip. Null: the surface ahead comes with the answers only.
  std::shared_ptr<const haptics::TissueSurface> surface;
  // A needle scene's tissue, from the join (haptics/needle.h): with kModel the station renders
  // the needle with its own model from its own tip, the answers correcting its tract and
  // punctures (haptics/needle_contact.h), so a layer's pop is felt on time at any delay. Null: not
  // a needle scene.
  std::shared_ptr<const haptics::NeedleTissueSpec> needle;
  // A cut scene's blade, from the join (haptics/blade.h): with kModel the station renders the
  // blade with its own fracture model from its own tip (the server's sees the same tips, so the
  // two cracks follow one path), so the puncture, the cutting force and a crossing of the cut are
  // felt on time at any delay. Null: not a cut scene.
  std::shared_ptr<const haptics::BladeParams> blade;
  // The station clock (sample times, round trips, the watchdog and its fade); null: the steady
  // clock. The device loop itself is paced by real time at rate_hz whatever this clock says.
  const Clock* clock = nullptr;
};

struct StationStats {
  uint64_t sent = 0, received = 0, dropped = 0;
  // Answers that arrived after a newer one (not applied: latest wins), and copies of one already
  // seen. Neither is loss.
  uint64_t stale = 0, duplicates = 0;
  // Stylus datagrams never answered, up to the newest answered one (either direction's loss; the
  // ones still in flight are not counted), and answers that came more than the watchdog's time
  // after the one before (late enough to be felt: the model was held or faded meanwhile).
  uint64_t lost = 0, late = 0;
  double rtt_p50_us = 0, rtt_p99_us = 0, rtt_p999_us = 0;
  double jitter_us = 0;  // mean |RTT_i − RTT_{i−1}|
  double loss = 0;       // lost / the newest answered stylus sequence
  // Times the force was faded for want of answers: the watchdog began to fade it, or the
  // channel was stopped while its server was silent (a held model faded by Stop).
  uint64_t watchdog_fades = 0;
  uint64_t scene_chunks = 0;    // SceneFrame datagrams received
  uint64_t scene_bytes = 0;     // and their bytes, as sent (header and tag included)
  uint64_t topology_bytes = 0;  // of which a cut's faces' chunks
  uint64_t marks = 0;           // a palpation's marks the server placed
  // A needle scene: pops the station rendered from its own model before the server's answers
  // said so, and times it took the server's word over its own (haptics/needle_contact.h).
  uint64_t needle_local_pops = 0, needle_corrections = 0;
  // A cut scene: punctures the station rendered from its own blade model.
  uint64_t blade_local_punctures = 0;
  double passivity_energy_dissipated = 0;  // J the controller removed
  // The passivity observer's record of the force held over each servo interval against that
  // interval's motion: positive work on the hand, and work the hand put in (J). Their difference
  // is the energy the rendering gave the hand; > 0 means the loop was active.
  double energy_to_hand = 0, energy_from_hand = 0;
  // The energy the server's answers say its force gave the tool (J; the network passivity's
  // budget for energy_to_hand).
  double tissue_released = 0;
  // The lowest the two-port's account fell (J, client/net/passivity.h kNetwork, kept in either
  // mode): below −E₀ the hand was given energy the tissue's record did not cover.
  double network_balance_min = 0;
  uint64_t force_log_rows = 0, force_log_dropped = 0;
  double max_force = 0;  // N rendered
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
  // Any thread: answers that said the session moved to another node (haptics::
  // kEventSessionMoved; not forces, not counted as received).
  uint64_t moved_notices() const;
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
