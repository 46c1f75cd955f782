// Four-handed training measured in a closed loop (common/sim/guidance.h): two simulated hands
// (client/device/virtual_hand.h), a trainee's and an instructor's, each at a real station channel
// through its own impairment relay (bench/relay), into one real UDP endpoint running the scene's
// Simulation: the trainee on the session's channel, the instructor on an instructor's channel
// (server::InstructorChannel), both answered on the session's lane. A run gives what each hand
// lived, the tool the tissue met (the simulation's telemetry, as the server's sampler reads it),
// and the trainee's trial record. tests/bench/four_hands_test.cpp runs it in CI.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "bench/relay/impairment.h"
#include "client/device/virtual_hand.h"
#include "client/net/station_channel.h"
#include "common/core/expected.h"
#include "common/scoring/metrics.h"
#include "common/sim/guidance.h"
#include "common/sim/scene.h"

namespace vsurg::bench::wan {

// The tool as the simulation published it (every 8th trainee sample).
struct ToolSample {
  haptics::Vec3 tool = haptics::Vec3::Zero();   // m
  haptics::Vec3 tip = haptics::Vec3::Zero();    // m, the trainee's own tip of that sample
  haptics::Vec3 force = haptics::Vec3::Zero();  // N, the tissue's on the tool
  double alpha = 0;
  uint32_t mode = 0;
  size_t cycle = 0;  // the trainee hand's servo cycle when it was read
  double time = 0;   // s, the trainee station's clock of the sample it was published with
};

struct FourHandsOptions {
  sim::Scene scene;
  // Each hand's intended trajectory, held at its first pose for lead_in_s first (the stations'
  // start-up gates open on every profile before the task begins).
  std::vector<haptics::StylusSample> trainee_plan, instructor_plan;
  bool instructor = true;  // false: the trainee alone (the reference)
  relay::Profile trainee_profile, instructor_profile;
  sim::GuideRequest guide{sim::GuideMode::kGuide, 0.5};  // asked for from the start
  // Mode changes during the run: at the trainee hand's servo cycle (lead-in included), a request.
  std::vector<std::pair<size_t, sim::GuideRequest>> changes;
  client::HandImpedance trainee_grip = client::RelaxedGrip();
  client::HandImpedance instructor_grip = client::RelaxedGrip();
  // The instructor's channel fed by a hostile sender instead of a station: every millisecond a
  // datagram sealed with the instructor's key carrying NaN, a tip 10 m away, a jump of up to
  // 3 cm, or a time of 1e308 s, and one of unsealed noise (what one participant's broken or
  // malicious station could send; the trainee must not notice beyond the guidance itself).
  bool hostile_instructor = false;
  double lead_in_s = 1.0;
  // The instructor's plan begins this much later than the trainee's (s): an observing hand that
  // follows the trainee's path as it reaches it over the two links, not one that knows it ahead.
  double instructor_lag_s = 0;
  // An instructor who corrects what they see: the tool, shown at their station a down link's
  // delay after the simulation published it, against `correct_towards` (the tool's path as the
  // expert alone made it). Their hand's intent moves from its plan by kp·e + ki·∫e dt, e from the
  // tool to the path's closest point within a second of the same moment of the trainee's clock,
  // at most kMaxCorrection. Empty: the instructor plays the plan as it is.
  std::vector<ToolSample> correct_towards;
  double correction_kp = 1.5;                      // 1
  double correction_ki = 8.0;                      // 1/s
  static constexpr double kMaxCorrection = 0.005;  // m
  double settle_s = 0.5;
  uint64_t seed = 1;
  std::string cache_dir;
};

struct FourHandsRun {
  std::vector<client::HandSample> trainee, instructor;  // per servo cycle, after the lead-in
  client::StationStats trainee_station, instructor_station;
  std::vector<ToolSample> tool;
  scoring::TrialMetrics metrics;    // the trainee's trial record
  double score_but_smoothness = 0;  // scoring::ScoreButSmoothness of it
  uint64_t trainee_applied = 0;     // the trainee's datagrams the endpoint applied
  uint64_t hostile_sent = 0;  // hostile_instructor: datagrams sent to the instructor's channel
};

Expected<FourHandsRun> RunFourHands(const FourHandsOptions& options);

// Every mode and change in one trial, for a run that starts observing: guide at α = 0.5 0.6 s
// after the lead-in's `lead_cycles`, take over at 1.5 s, hand back at 2.5 s.
std::vector<std::pair<size_t, sim::GuideRequest>> EveryModeChange(size_t lead_cycles);

// RMS distance of the tool from the path the reference run's tool took (time-free: the nearest
// point of its polyline), over both runs' tool samples after the lead-in, m. The reference is
// the expert alone: its path includes the tissue's push back on the hand.
double PathError(const FourHandsRun& run, const FourHandsRun& reference, size_t lead_cycles);
double PeakToolForce(const FourHandsRun& run);  // N
// Σ F_k·(x_{k+1} − x_k) over a hand's held intervals, J (> 0: the loop gave the hand energy).
double EnergyToHand(const std::vector<client::HandSample>& trace);
double PeakForce(const std::vector<client::HandSample>& trace);  // N, what the device rendered

// Haptic playback (observe): how closely the instructor's rendered force follows the trainee's.
// The instructor feels it later by the path from the trainee's hand through the server to the
// instructor's (up to `max_lag_s`): `rms_ratio` is RMS|F_i(t + lag) − F_t(t)| / RMS|F_t| over the
// trainee's cycles in contact (|F_t| > 0.05 N) at the lag that makes it least, `raw_ratio` the
// same with no lag; servo cycles are 1 ms on both hands.
struct PlaybackError {
  double rms_ratio = 0, raw_ratio = 0;
  double lag_s = 0;
  size_t cycles = 0;  // in contact
};
PlaybackError ObserverError(const FourHandsRun& run, double max_lag_s = 0.5);
// The lag (s) of an observing hand that follows the trainee's path as it reaches it: the
// trainee's link up and the instructor's down, each profile's base one-way delay
// (FourHandsOptions::instructor_lag_s).
inline double FollowingLag(const FourHandsOptions& o) {
  return 1e-3 * (o.trainee_profile.up.base_ms + o.instructor_profile.down.base_ms);
}

}  // namespace vsurg::bench::wan
