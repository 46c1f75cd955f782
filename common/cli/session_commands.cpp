// vsurg-sim run and trainee: a scene driven by a recorded or scripted stylus trajectory.
#include "common/cli/commands.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <numbers>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "common/core/file.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/obj_io.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "common/sim/contact_law.h"
#include "common/sim/limb_scene.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/tissue/coil_calibration.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::cli::commands {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

Expected<sim::Scene> SceneOption(const ArgParser& p) {
  auto scene = sim::LoadSceneByName(p.String("scene"));
  if (!scene.ok()) {
    Error e = scene.error();
    e.field = "--scene";
    return e;
  }
  return scene;
}

}  // namespace

int Run(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim run",
      "Replays a stylus trajectory headless through a scene's simulation (contact, "
      "grasp-and-twist,\n"
      "device safety, deformation, scoring) and prints the trial metrics and force statistics.\n"
      "The trajectory is a CSV with the header t,x,y,z,qw,qx,qy,qz,buttons (s, m, unit\n"
      "quaternion, button bits: 1 = grasp); `vsurg-sim trainee` writes scripted ones.");
  p.Option("scene", Kind::kString, "scene name in scenes/ (e.g. arm-torsion) or a .json path", true)
      .Option("trajectory", Kind::kString, "trajectory CSV", true)
      .Option("json", Kind::kFlag, "print one JSON object");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto scene = SceneOption(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  auto samples = sim::ReadTrajectoryCsv(p.String("trajectory"));
  if (!samples.ok()) {
    err << p.command() << ": --trajectory: " << samples.error().message << "\n";
    return kExitUsage;
  }
  sim::SimulationOptions options;
  options.threaded = false;  // deterministic replay: deformation stepped in simulated time
  auto simulation = sim::Simulation::Create(*scene, options);
  if (!simulation.ok()) {
    err << p.command() << ": cannot build scene '" << scene->name
        << "': " << simulation.error().message << "\n";
    return kExitRuntime;
  }
  sim::Simulation& s = **simulation;
  double force_sum = 0;
  int forces = 0, contacts = 0, grasps = 0;
  std::map<std::string, int> events;
  const std::pair<uint32_t, const char*> kEvents[] = {
      {haptics::kEventNonFiniteInput, "non_finite_input"},
      {haptics::kEventOutOfWorkspace, "out_of_workspace"},
      {haptics::kEventForceClamped, "force_clamped"},
      {haptics::kEventRateLimited, "rate_limited"},
      {haptics::kEventGated, "gated"},
      {haptics::kEventStiffnessClamped, "stiffness_clamped"},
      {haptics::kEventOverload, "overload"},
      {haptics::kEventOutsideModel, "outside_model"}};
  double peak = 0;
  s.Replay(*samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    const double f = c.force.norm();
    peak = std::max(peak, f);
    force_sum += f;
    ++forces;
    contacts += c.contact;
    grasps += (c.events & haptics::kEventGraspStart) != 0;
    for (const auto& [bit, name] : kEvents) {
      if (c.events & bit) ++events[name];
    }
  });
  const scoring::TrialMetrics m = s.Metrics();
  if (p.Flag("json")) {
    json j;
    j["scene"] = scene->name;
    j["samples"] = samples->size();
    j["metrics"] = scoring::TrialMetricsToJson(m);
    j["peak_force"] = peak;
    j["mean_force"] = forces ? force_sum / forces : 0.0;
    j["contact_samples"] = contacts;
    j["grasps"] = grasps;
    j["events"] = events;
    j["deformation_updates"] = s.deformation_updates();
    out << j.dump() << "\n";
    return 0;
  }
  char line[400];
  std::snprintf(
      line, sizeof line,
      "%s: %zu samples, peak force %.3f N (after device limits), mean %.3f N\n"
      "completed %s in %.2f s, task error %.4g, %.2f s over the force limit, overloads %d\n"
      "path %.3f m, RMS jerk %.3g m/s^3, score %.1f / 10 (before gates %.1f)\n",
      scene->name.c_str(), samples->size(), peak, forces ? force_sum / forces : 0.0,
      m.completed ? "yes" : "no", m.completion_time, m.task_error, m.time_over_force_limit,
      m.overload_events, m.path_length, m.rms_jerk, m.score, m.raw_score);
  out << line;
  if (scene->task.kind == scoring::TaskKind::kInsert) {
    std::snprintf(line, sizeof line,
                  "needle: depth error %.2f mm, path %.2f mm off the target, punctures %d "
                  "(%d beyond the path's own), back-wall breaches %d, lateral strain %.1f%%\n",
                  1e3 * m.depth_error, 1e3 * m.path_deviation, m.punctures, m.extra_punctures,
                  m.back_wall_breaches, 100 * m.lateral_strain);
    out << line;
  }
  return 0;
}

int Trainee(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim trainee",
      "Writes a scripted trainee's stylus trajectory for a scene's task, as the CSV `run` reads:\n"
      "good (smooth, on target), hesitant (slow, stepwise corrections), rough (fast, jerky,\n"
      "overshooting, over the force limit).");
  p.Option("scene", Kind::kString, "scene name or .json path", true)
      .Option("style", Kind::kString, "good, hesitant or rough", false, "good")
      .Option("rate", Kind::kDouble, "samples per second", false, "1000")
      .Option("seed", Kind::kInt, "tremor seed (rough)", false, "1")
      .Option("out", Kind::kString, "CSV file to write", true);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto scene = SceneOption(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  auto style = sim::ParseTraineeStyle(p.String("style"));
  if (!style.ok())
    return UsageError(err, p.command(), InvalidArgument("--style", style.error().message));
  auto samples =
      sim::ScriptedTrainee(*scene, *style, p.Double("rate"), static_cast<unsigned>(p.Int("seed")));
  if (!samples.ok())
    return UsageError(err, p.command(), InvalidArgument("--rate", samples.error().message));
  if (Status st = sim::WriteTrajectoryCsv(*samples, p.String("out")); !st.ok()) {
    err << p.command() << ": --out: " << st.error().message << "\n";
    return kExitRuntime;
  }
  out << "wrote " << samples->size() << " samples to " << p.String("out") << "\n";
  return 0;
}

// The tissue's law under the proxy (sim::MeasureContactLaw): the viscoelastic fit at the good
// scripted trainee's press and the static curve, for the scene file's haptics
// "tissue_stiffness", "tissue_damping" and "tissue_curve", which a
// station's own surface renders a contact's first round trip with (haptics/tissue_surface.h).
int ContactLaw(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-sim contact-law",
              "Presses a scene as the server's tissue and prints the contact's tissue law: the\n"
              "viscoelastic fit at the good scripted trainee's press (k_t, N/m; b, N*s/m) and the\n"
              "tissue's static curve (yield m, force N), for the scene file's haptics.");
  p.Option("scene", Kind::kString, "scene name in scenes/ or a .json path (a press scene)", true)
      .Option("curve", Kind::kFlag, "also print the static curve (depth, yield, force)");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto scene = SceneOption(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  if (scene->task.kind != scoring::TaskKind::kPress)
    return UsageError(err, p.command(), InvalidArgument("--scene", "not a press scene"));
  auto law = sim::MeasureContactLaw(*scene);
  if (!law.ok()) {
    err << p.command() << ": " << scene->name << ": " << law.error().message << "\n";
    return kExitRuntime;
  }
  char line[240];
  if (p.Flag("curve")) {
    out << "depth_mm,yield_mm,force_n\n";
    for (const auto& c : law->curve) {
      std::snprintf(line, sizeof line, "%.3f,%.4f,%.5f\n", c.depth * 1e3, c.yield * 1e3, c.force);
      out << line;
    }
  }
  std::snprintf(line, sizeof line, "\"tissue_stiffness\": %.4g, \"tissue_damping\": %.4g,",
                law->stiffness, law->damping);
  out << line << "\n";
  if (law->tissue.count == 0) {  // never settled in contact: nothing the scene file could take
    err << p.command() << ": " << scene->name << ": no depth settled in contact: no tissue_curve\n";
    return 0;
  }
  out << "\"tissue_curve\": [";
  for (int i = 0; i < law->tissue.count; ++i) {
    std::snprintf(line, sizeof line, "%s[%.4g, %.4g]", i ? ", " : "", law->tissue.yield[i],
                  law->tissue.force[i]);
    out << line;
  }
  out << "]\n";
  return 0;
}

}  // namespace vsurg::cli::commands
