// Haptics across a network, measured in a closed loop: a simulated hand (client/device/
// virtual_hand.h) at a real station channel, through the impairment relay (bench/relay), to a
// real UDP endpoint running the scene's Simulation, all on loopback in one process. A run gives
// what the hand lived (position and the force held, per servo cycle), the link's figures from
// both ends, and the trial's score; Compare() sets a run against the same run without
// impairment. `vsurg-bench wan` runs the grid (docs/BENCHMARKS.md "Haptics across networks");
// tests/bench/wan_test.cpp runs two cells of it in CI.
#pragma once

#include <string>
#include <vector>

#include "bench/relay/impairment.h"
#include "client/device/virtual_hand.h"
#include "client/net/station_channel.h"
#include "common/core/expected.h"
#include "common/sim/scene.h"
#include "common/sim/trajectory.h"

namespace vsurg::bench::wan {

struct RunOptions {
  sim::Scene scene;
  // The hand's intended trajectory. RunOnce holds its first pose for lead_in_s first, so that
  // the station's start-up gate (which waits for the first answer, 50 quiet cycles and a 0.5 s
  // ramp) is open on every profile before the task begins; traces start after the lead-in.
  std::vector<haptics::StylusSample> plan;
  double lead_in_s = 1.0;
  relay::Profile profile;
  uint64_t seed = 1;
  client::LocalRendering rendering = client::LocalRendering::kModel;
  client::HandImpedance grip = client::RelaxedGrip();
  bool passivity = true;
  client::PassivityMode passivity_mode = client::PassivityMode::kLocal;
  bool exact_grasp = true;    // StationOptions::exact_grasp (false: a grasp's first order alone)
  double model_hold_s = 1.0;  // StationOptions::model_hold_s (0: a silence fades every model)
  double deadband = 0;  // the station's Weber fraction (StationOptions::deadband); 0: every cycle
  double contact_heartbeat_s = 0.015;  // StationOptions::deadband_contact_heartbeat_s
  // The tissue's surface at the station from its join (StationOptions::surface); false: the
  // surface ahead from the answers alone.
  bool station_surface = true;
  double settle_s = 0.5;  // run on after the plan ends
  std::string cache_dir;  // reduced models' cache ("" = the default)
};

struct Run {
  std::vector<client::HandSample> trace;  // one per servo cycle, device time
  client::StationStats station;
  uint64_t up_datagrams = 0, down_datagrams = 0;  // sent toward the relay, each way
  double seconds = 0;                             // wall time of the exchange
  double score = 0;                               // the server's trial score
  // The score's parts but smoothness (accuracy, time, force: 0–8 points, before the gates).
  // Smoothness is read from the stylus samples' times, which a station stamps with its clock
  // when it sends them: behind a loaded host's late servo cycles the virtual hand's one-period
  // steps arrive stamped closer together than they moved, which reads as jerk (a real device is
  // read at the time it is sampled). The same unimpaired trial scored 9.06–9.22 beside two CPU
  // hogs, all of it smoothness (RMS jerk 15–22 m/s³); the task error and completion time were the
  // same in every run.
  double score_but_smoothness = 0;
  double server_peak_force = 0;  // N, what the server scored
};

Expected<Run> RunOnce(const RunOptions& options);

struct Figures {
  double rms_error_pct = 0;  // force RMS error, % of the reference's peak
  // Contact felt later than in the reference, in servo cycles (1 ms each) of the hand's own
  // time: a functional figure, not a wall-clock one (the CSV's onset_delay_ms column).
  double onset_delay_cycles = 0;
  double onset_extra_mm = 0;     // deeper along the contact normal when it was first felt
  double stiffness_pct = 0;      // displayed stiffness (force over depth), % of the reference's
  double energy_to_hand_mj = 0;  // Σ F·Δx over held intervals, mJ (> 0: the loop gave energy)
  double energy_excess_mj = 0;   // … beyond the reference's
  double oscillation_n = 0;      // RMS of the force above 30 Hz, N
  double peak_force_n = 0;
  // The tissue sticking to the tool after it has let go: the force beyond the reference's from
  // 20 ms to 300 ms after the grasp's release, or (no grasp) the largest force from 20 ms after
  // the reference last felt anything; on 20 ms means, each wholly after those 20 ms of grace.
  double phantom_n = 0;
  size_t phantom_cycle = 0;       // the last cycle of the mean that gave phantom_n
  double up_hz = 0, down_hz = 0;  // datagrams per second each way
  double score = 0;
  double score_but_smoothness = 0;  // Run::score_but_smoothness
  // A needle's pops (Pops): how many the run felt beside the reference's, and the largest delay
  // of a pop felt against the reference's same pop, in servo cycles of the hand's own time.
  int pops = 0, reference_pops = 0;
  double pop_delay_cycles = 0;
};

// The cycles at which a needle's boundary gave way as the hand felt it: the force's norm fell
// from at least 0.3 N by 0.2 N and 30% or more within 3 cycles (the friction and the cutting
// never fall that fast).
std::vector<size_t> Pops(const std::vector<client::HandSample>& trace);

// A quick palpation of a press scene: from 6 cm above the surface point the scripted trainees
// press (twice the scene's surface-ahead reach, so no answer about the approach carries the
// surface), straight down along the normal to 5 mm deep in 0.35 s (the surface reached about
// 0.3 s in), held 1 s, and back up in 0.4 s. At 1 kHz.
Expected<std::vector<haptics::StylusSample>> TapPlan(const sim::Scene& scene);

// `stiffness` is only meaningful for press scenes (0 otherwise); contact is a force ≥ 0.1 N.
Figures Compare(const Run& run, const Run& reference, bool press_scene);

// The scenes the grid runs: sphere-palpation-256 (soft), the same sphere at an Omni-class 700 N/m
// ("sphere-palpation-256@700"), arm-torsion, organ-surface-twist, needle-vessel, lump-search
// (holding kGridLump, not a drawn case); by name.
Expected<sim::Scene> GridScene(const std::string& name);

// A palpation's plan for the grid: the scripted examiner of `style` (sim::PalpationSearch; good:
// the expert) searches the scene closed on its answers without a network, and the `window_s`
// seconds of its samples about its deepest press nearest the lump are played open loop, from the
// hand's highest point of the half second before (a whole search takes minutes; the stretch
// carries a few presses on and around the lump).
extern const tissue::Inclusion kGridLump;
Expected<std::vector<haptics::StylusSample>> SearchPlan(const sim::Scene& scene,
                                                        sim::TraineeStyle style, double window_s);

}  // namespace vsurg::bench::wan
