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
  double lead_in_s = 1.0;
  double settle_s = 0.5;
  uint64_t seed = 1;
  std::string cache_dir;
};

// The tool as the simulation published it (every 8th trainee sample).
struct ToolSample {
  haptics::Vec3 tool = haptics::Vec3::Zero();   // m
  haptics::Vec3 force = haptics::Vec3::Zero();  // N, the tissue's on the tool
  double alpha = 0;
  uint32_t mode = 0;
  size_t cycle = 0;  // the trainee hand's servo cycle when it was read
  double time = 0;   // s, the trainee station's clock of the sample it was published with
};

struct FourHandsRun {
  std::vector<client::HandSample> trainee, instructor;  // per servo cycle, after the lead-in
  client::StationStats trainee_station, instructor_station;
  std::vector<ToolSample> tool;
  scoring::TrialMetrics metrics;  // the trainee's trial record
  uint64_t trainee_applied = 0;   // the trainee's datagrams the endpoint applied
};

Expected<FourHandsRun> RunFourHands(const FourHandsOptions& options);

// RMS distance of the tool from the path the reference run's tool took (time-free: the nearest
// point of its polyline), over both runs' tool samples after the lead-in, m. The reference is
// the expert alone: its path includes the tissue's push back on the hand.
double PathError(const FourHandsRun& run, const FourHandsRun& reference, size_t lead_cycles);
double PeakToolForce(const FourHandsRun& run);  // N
// Σ F_k·(x_{k+1} − x_k) over a hand's held intervals, J (> 0: the loop gave the hand energy).
double EnergyToHand(const std::vector<client::HandSample>& trace);
double PeakForce(const std::vector<client::HandSample>& trace);  // N, what the device rendered

}  // namespace vsurg::bench::wan
