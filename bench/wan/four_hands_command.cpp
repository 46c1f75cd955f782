// vsurg-bench four-hands: four-handed training in closed loop (bench/wan/four_hands.h) over every
// pair of relay profiles, in one run. Three tables, each written to DIR as CSV and printed:
//   modes.csv     every trainee × instructor profile pair through observe → guide at 0.5 → take
//                 over → hand back (a rough trainee, a steady expert): each hand's net energy
//                 from the loop beside the no-delay trainee alone's, the peak forces against the
//                 device's limit, the fastest α change;
//   playback.csv  observe with the trainee on the lab's LAN and the instructor on each profile:
//                 the instructor's rendered force against the trainee's (ObserverError), for a
//                 hand that follows the trainee's path as it reaches it and one that anticipates;
//   guidance.csv  the rough trainee alone and guided at α = 0.5 by the expert, who plays the
//                 plan or corrects where it sees the tool stray from its path
//                 (FourHandsOptions::correct_towards), at lan and continental: path error from
//                 the expert's own path and the peak force.
// docs/BENCHMARKS.md "Four-handed training".
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "bench/wan/four_hands.h"
#include "bench/wan/wan.h"
#include "common/core/args.h"
#include "common/core/format.h"
#include "common/sim/trajectory.h"

namespace vsurg::bench {

namespace {

namespace fs = std::filesystem;
using wan::FourHandsOptions;
using wan::FourHandsRun;

constexpr size_t kLead = 1000;  // the lead-in's servo cycles (FourHandsOptions::lead_in_s)

struct Plans {
  sim::Scene scene;
  std::vector<haptics::StylusSample> rough, steady;
};

FourHandsOptions Options(const Plans& p, const std::string& trainee,
                         const std::string& instructor) {
  FourHandsOptions o;
  o.scene = p.scene;
  o.trainee_plan = p.rough;
  o.instructor_plan = p.steady;
  o.instructor_grip = client::TensedGrip();
  o.trainee_profile = *relay::ProfileByName(trainee);
  o.instructor_profile = *relay::ProfileByName(instructor);
  return o;
}

Expected<FourHandsRun> Run(const FourHandsOptions& o, const std::string& what) {
  auto r = wan::RunFourHands(o);
  if (!r.ok()) std::cerr << "vsurg-bench four-hands: " << what << ": " << r.error().message << "\n";
  return r;
}

// The largest change of α per second of the trainee station's clock between two reads.
double FastestAlpha(const FourHandsRun& r) {
  double top = 0;
  for (size_t k = 1; k < r.tool.size(); ++k) {
    const double dt = r.tool[k].time - r.tool[k - 1].time;
    if (dt > 0) top = std::max(top, std::abs(r.tool[k].alpha - r.tool[k - 1].alpha) / dt);
  }
  return top;
}

int Modes(const Plans& p, const std::vector<std::string>& profiles, const fs::path& dir) {
  FourHandsOptions alone = Options(p, "none", "none");
  alone.instructor = false;
  auto ref = Run(alone, "the trainee alone");
  if (!ref.ok()) return 1;
  const double e_ref = wan::EnergyToHand(ref->trainee);
  std::ofstream csv(dir / "modes.csv");
  csv << "trainee,instructor,energy_trainee_mj,energy_instructor_mj,energy_alone_mj,"
         "excess_mj,peak_trainee_n,peak_instructor_n,limit_n,alpha_per_s\n";
  std::cout << "modes (observe, guide 0.5, take over, hand back); trainee alone, no delay: "
            << Fixed(1e3 * e_ref, 3) << " mJ to the hand\n";
  for (const std::string& t : profiles)
    for (const std::string& i : profiles) {
      FourHandsOptions o = Options(p, t, i);
      o.guide = {sim::GuideMode::kObserve, 0};
      o.changes = wan::EveryModeChange(kLead);
      auto r = Run(o, t + " x " + i);
      if (!r.ok()) return 1;
      const double et = wan::EnergyToHand(r->trainee), ei = wan::EnergyToHand(r->instructor);
      const double excess = et + ei - e_ref;
      csv << t << "," << i << "," << 1e3 * et << "," << 1e3 * ei << "," << 1e3 * e_ref << ","
          << 1e3 * excess << "," << wan::PeakForce(r->trainee) << ","
          << wan::PeakForce(r->instructor) << "," << p.scene.haptics.limits.max_force << ","
          << FastestAlpha(*r) << "\n";
      std::cout << "  trainee " << t << ", instructor " << i << ": energy " << Fixed(1e3 * et, 3)
                << " + " << Fixed(1e3 * ei, 3) << " mJ (excess over alone "
                << Fixed(1e3 * excess, 3) << "), peaks " << Fixed(wan::PeakForce(r->trainee), 2)
                << " / " << Fixed(wan::PeakForce(r->instructor), 2) << " N, alpha "
                << Fixed(FastestAlpha(*r), 2) << "/s\n";
    }
  return 0;
}

int Playback(const Plans& p, const std::vector<std::string>& profiles, const fs::path& dir) {
  std::ofstream csv(dir / "playback.csv");
  csv << "trainee,instructor,hand,instructor_lag_ms,rms_ratio,raw_ratio,lag_ms,cycles\n";
  std::cout << "observe (the trainee on lan): the instructor's force against the trainee's\n";
  // The instructor's hand as the trainee's (the same plan, the same relaxed grip), led by the
  // coupling to where the trainee's tool is, so what differs is what the two links and the two
  // stations' rendering add. Two hands: one that follows the trainee's path as it reaches it
  // (its plan later by the two links' mean one-way delay, trainee → server → instructor), and
  // one that anticipates it by that delay (the same plan at the same time), whose lead the
  // coupling pulls back: k_c·v·delay on top of the tissue's force.
  for (const std::string& i : profiles)
    for (const bool follows : {true, false}) {
      FourHandsOptions o = Options(p, "lan", i);
      o.trainee_plan = p.steady;
      o.instructor_plan = p.steady;
      o.instructor_grip = client::RelaxedGrip();
      o.guide = {sim::GuideMode::kObserve, 0};
      if (follows) o.instructor_lag_s = wan::FollowingLag(o);
      const char* hand = follows ? "follows" : "anticipates";
      auto r = Run(o, std::string("observe at ") + i);
      if (!r.ok()) return 1;
      const wan::PlaybackError e = wan::ObserverError(*r);
      csv << "lan," << i << "," << hand << "," << 1e3 * o.instructor_lag_s << "," << e.rms_ratio
          << "," << e.raw_ratio << "," << 1e3 * e.lag_s << "," << e.cycles << "\n";
      std::cout << "  instructor " << i << ", a hand that " << hand << ": "
                << Fixed(100 * e.rms_ratio, 1) << "% RMS at a lag of " << Fixed(1e3 * e.lag_s, 0)
                << " ms (" << Fixed(100 * e.raw_ratio, 1) << "% unaligned), " << e.cycles
                << " cycles in contact\n";
    }
  return 0;
}

int Guidance(const Plans& p, const fs::path& dir) {
  FourHandsOptions expert_alone = Options(p, "lan", "lan");
  expert_alone.instructor = false;
  expert_alone.trainee_plan = p.steady;
  expert_alone.trainee_grip = client::TensedGrip();
  auto expert = Run(expert_alone, "the expert alone");
  expert_alone.seed = 2;
  auto again = Run(expert_alone, "the expert alone again");
  if (!expert.ok() || !again.ok()) return 1;
  // The measure's floor: the expert's own second run against the first (the relay's and the
  // hands' randomness, the tissue's response to a hand that is never quite the same).
  const double floor = wan::PathError(*again, *expert, kLead);
  std::ofstream csv(dir / "guidance.csv");
  csv << "profile,path_alone_mm,path_guided_mm,path_correcting_mm,path_floor_mm,peak_alone_n,"
         "peak_guided_n,peak_correcting_n,peak_expert_n\n";
  std::cout << "guidance (rough trainee, steady expert at alpha 0.5: playing the plan, and "
               "correcting the tool it sees); the expert against its own second run: "
            << Fixed(1e3 * floor, 2) << " mm\n";
  for (const char* profile : {"lan", "continental"}) {
    FourHandsOptions o = Options(p, profile, profile);
    o.instructor = false;
    auto alone = Run(o, std::string("alone at ") + profile);
    o.instructor = true;
    auto guided = Run(o, std::string("guided at ") + profile);
    o.correct_towards = expert->tool;
    auto correcting = Run(o, std::string("guided, correcting, at ") + profile);
    if (!alone.ok() || !guided.ok() || !correcting.ok()) return 1;
    const double a = wan::PathError(*alone, *expert, kLead);
    const double g = wan::PathError(*guided, *expert, kLead);
    const double c = wan::PathError(*correcting, *expert, kLead);
    const double pa = wan::PeakToolForce(*alone), pg = wan::PeakToolForce(*guided);
    const double pc = wan::PeakToolForce(*correcting), pe = wan::PeakToolForce(*expert);
    csv << profile << "," << 1e3 * a << "," << 1e3 * g << "," << 1e3 * c << "," << 1e3 * floor
        << "," << pa << "," << pg << "," << pc << "," << pe << "\n";
    std::cout << "  " << profile << ": path error " << Fixed(1e3 * a, 2) << " mm alone, "
              << Fixed(1e3 * g, 2) << " guided, " << Fixed(1e3 * c, 2) << " correcting; peak "
              << Fixed(pa, 2) << " N alone, " << Fixed(pg, 2) << " guided, " << Fixed(pc, 2)
              << " correcting (the expert's " << Fixed(pe, 2) << ")\n";
  }
  return 0;
}

}  // namespace

int FourHands(const std::vector<std::string>& args) {
  cli::ArgParser parser("vsurg-bench four-hands",
                        "four-handed training in closed loop over every pair of relay profiles");
  using Kind = cli::ArgParser::Kind;
  parser
      .Option("profiles", Kind::kString, "relay profiles, comma-separated", false,
              "lan,metro,regional,continental,intercontinental")
      .Option("scene", Kind::kString, "a grid scene", false, "sphere-palpation-256")
      .Option("tables", Kind::kString, "which tables, comma-separated", false,
              "modes,playback,guidance")
      .Option("out", Kind::kString, "directory for the CSV files", false, "four-hands");
  if (auto rc = cli::ParseOrExit(parser, args, std::cout, std::cerr)) return *rc;
  Plans p;
  auto scene = wan::GridScene(parser.String("scene"));
  if (!scene.ok()) return cli::UsageError(std::cerr, parser.command(), scene.error());
  p.scene = *scene;
  p.rough = *sim::ScriptedTrainee(p.scene, sim::TraineeStyle::kRough);
  p.steady = *sim::ScriptedTrainee(p.scene, sim::TraineeStyle::kSteady);
  const std::vector<std::string> profiles = parser.List("profiles");
  for (const std::string& name : profiles)
    if (auto known = relay::ProfileByName(name); !known.ok())
      return cli::UsageError(std::cerr, parser.command(), known.error());
  const std::vector<std::string> tables = parser.List("tables");
  const auto wants = [&](const std::string& t) {
    return std::find(tables.begin(), tables.end(), t) != tables.end();
  };
  for (const std::string& t : tables)
    if (t != "modes" && t != "playback" && t != "guidance")
      return cli::UsageError(
          std::cerr, parser.command(),
          Error{ErrorCode::kInvalidArgument,
                "--tables: \"" + t + "\" is not modes, playback or guidance", "cli"});
  const fs::path dir = parser.String("out");
  fs::create_directories(dir);
  if (int rc = wants("modes") ? Modes(p, profiles, dir) : 0; rc != 0) return rc;
  if (int rc = wants("playback") ? Playback(p, profiles, dir) : 0; rc != 0) return rc;
  return wants("guidance") ? Guidance(p, dir) : 0;
}

}  // namespace vsurg::bench
