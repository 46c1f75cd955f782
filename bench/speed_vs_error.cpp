// vsurg-bench speed-vs-error: every model on the same scenes against the same reference
// (DESIGN.md "Speed against error"). See speed_vs_error.h for the command's contract.
//
// Scenes and references
//   arm-ramp     forearm, fixed at the elbow, a torque ramped at the wrist to the coil-spring
//   paper's 2.07 N·m.
//                Reference: tapered Saint-Venant torsion with the effective shear modulus that
//                gives the arm scene's twist at 2.07 N·m (60°), i.e. the stiffness the scene uses.
//   arm-haptic   the same forearm with the tissue's own G = 12 kPa and a haptic-scale 0.02 N·m.
//   calf-ramp    the calf to 2.07 N·m, effective modulus as the calf scene (30°).
//   sphere-palpation  a 5 cm ball fixed on its lower cap, pressed on top by 0.2 N spread over a
//                1 cm cap. Reference: the finest FEM (no closed form exists).
//   kidney-palpation  the kidney of scenes/kidney-palpation.json (an STL read by assimp,
//                tetrahedralised by CGAL), held on its lower fifth, pressed on its top like the
//                sphere. Reference: the FEM of the same surface at 4 mm tetrahedra.
//   organ-twist  organ-surface-twist: forceps twist the top of the 5 cm ball (held on its lower
//                fifth) to the task's 30°. Reference: the 20-cell FEM's twist field about the
//                surface normal for a torque on the jaws' disc, turned exactly.
//   lump-search  the palpation pad (12 × 12 × 4 cm on a table) holding a 10 mm lump five times as
//                stiff 15 mm down, pressed above it like the sphere. Reference: the
//                heterogeneous FEM at twice the scene's grid in each direction.
// Markers: ten, like the coil-spring paper Fig. 8. Limbs: on the top of the limb at z = (k − ½)/10
// · L from the fixed end (marker 10 is next to the grasp); sphere: along a meridian from the pole,
// polar angle 5°·(k − 1); kidney: on its upper side from the top along x, 5 mm apart; pad: on
// its top along x, 5 mm apart, the press between the fifth and the sixth. Each model
// reads each marker at its own nearest surface vertex, and the reference is evaluated at that same
// rest point. Error: |d_model − d_ref| (vectors), relative to the reference's largest marker
// displacement; RMS over the ten and max. Time per update: the median over repeats of what a
// deformation update costs the model in use: coil — one deformation for a new torque; FEM — one
// implicit step (h = 1 ms); mass-spring — advancing 1 ms (substeps where the integrator needs them
// to stay stable); ring layer — one step. Dynamic models are judged after a ramp (1 s) and a hold
// (2 s) at 1 kHz, so lag and ringing count against them; a diverged run is reported as such.
#include "bench/speed_vs_error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <iterator>
#include <map>

#include "bench/study/study.h"
#include "common/core/args.h"

namespace vsurg::bench {

using study::ChooseCheapest;
using study::Clock;
using study::Config;
using study::MarkdownTable;
using study::Num;
using study::Progress;
using study::RunLimbScenes;
using study::RunOrgan;
using study::RunPad;
using study::RunPatch;
using study::RunSphere;
using study::RunSurfaceTwist;
using study::SceneOut;
using study::UpdateBenchmarks;
using study::WriteCsv;
using study::WriteFigures;

namespace {

const char* const kParts[] = {"limbs", "laws", "sphere", "kidney", "organ-twist", "pad", "patch"};

bool KnownPart(const std::string& part) {
  return std::find(std::begin(kParts), std::end(kParts), part) != std::end(kParts);
}

// The study's parts (all, or the one `only` names), each scene's cheapest model within its budget
// chosen, with a progress bar of their steps.
std::vector<SceneOut> RunParts(const Config& cfg, const std::string& only) {
  const auto run = [&only](const std::string& part) { return only.empty() || only == part; };
  const int per_limb = 3 + (cfg.quick ? 1 : 2) + (cfg.quick ? 2 : 4) + 1 + 6;
  const int sphere = 1 + (cfg.quick ? 1 : 4) + (cfg.quick ? 1 : 2) + 1 + (cfg.quick ? 6 : 12) + 2;
  const int organ = cfg.quick ? 3 + 5 : 6 + 7;
  const int pad = cfg.quick ? 3 : 6;
  const int patch = cfg.quick ? 2 : 14;  // the quick run: the uncut lift, the scene's own lattice
  Progress progress(
      (run("limbs") ? 3 * per_limb : 0) +
      (run("laws")
           ? study::ArmLawSteps(cfg) + study::BallLawSteps(cfg) + study::OrganTwistLawSteps(cfg)
           : 0) +
      (run("sphere") ? sphere : 0) + (run("kidney") || run("organ-twist") ? organ : 0) +
      (run("pad") ? pad : 0) + (run("patch") ? patch : 0));
  std::vector<SceneOut> scenes;
  if (run("limbs")) scenes = RunLimbScenes(cfg, progress);
  if (run("laws")) {
    for (SceneOut& s : study::RunArmLaws(cfg, progress)) scenes.push_back(std::move(s));
    for (SceneOut& s : study::RunBallLaws(cfg, progress)) scenes.push_back(std::move(s));
    for (SceneOut& s : study::RunOrganTwistLaws(cfg, progress)) scenes.push_back(std::move(s));
  }
  if (run("sphere")) scenes.push_back(RunSphere(cfg, progress));
  if (run("kidney")) scenes.push_back(RunOrgan(cfg, progress));
  if (run("organ-twist")) scenes.push_back(RunSurfaceTwist(cfg, progress));
  if (run("pad")) scenes.push_back(RunPad(cfg, progress));
  if (run("patch")) scenes.push_back(RunPatch(cfg, progress));
  for (SceneOut& s : scenes) ChooseCheapest(s);
  return scenes;
}

// A scene file whose own model misses its own budget fails the study, loudly (a --quick run's
// coarse levels only warn): each is named on stderr; returns how many.
int ReportOverBudget(const std::string& command, const Config& cfg,
                     const std::vector<study::BudgetVerdict>& verdicts) {
  int over = 0;
  for (const study::BudgetVerdict& v : verdicts) {
    if (!v.in_study || v.meets) continue;
    ++over;
    std::cerr << command << ": " << (cfg.quick ? "warning" : "FAILED") << ": scenes/" << v.file
              << ".json: its model (" << (v.model.empty() ? "row missing" : v.setting) << ") is "
              << Num(100 * v.rms, 3) << "% RMS from the reference, over its budget of "
              << Num(100 * v.budget, 3) << "%\n";
  }
  return over;
}

}  // namespace

int SpeedVsError(const std::vector<std::string>& args) {
  cli::ArgParser p("vsurg-bench speed-vs-error",
                   "Every model on the same scenes against the same reference: time per update\n"
                   "against marker error (DESIGN.md \"Speed against error\"). Writes\n"
                   "speed-vs-error.csv, speed-vs-error.png (Pareto plot), marker8.png (marker 8\n"
                   "during the arm ramp) into --out, and the Markdown table into\n"
                   "docs/BENCHMARKS.md when --out is docs/ (or --benchmarks FILE).");
  p.Option("out", cli::ArgParser::Kind::kString, "output folder", false, "docs")
      .Option("quick", cli::ArgParser::Kind::kFlag, "coarse levels and short runs (under a minute)")
      .Option("benchmarks", cli::ArgParser::Kind::kString,
              "Markdown file to update (default: BENCHMARKS.md in --out when --out is docs)")
      .Option("only", cli::ArgParser::Kind::kString,
              "one part of the study: limbs, laws, sphere, kidney, organ-twist, pad or patch "
              "(the table is printed, no Markdown file is updated)");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  const std::string dir = p.String("out");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::cerr << p.command() << ": --out: cannot create " << dir << ": " << ec.message() << "\n";
    return 2;
  }
  Config cfg;
  cfg.quick = p.Flag("quick");
  cfg.repeats = cfg.quick ? 5 : 9;
  const auto t0 = Clock::now();
  const std::string only = p.Has("only") ? p.String("only") : "";
  if (!only.empty() && !KnownPart(only)) {
    std::cerr << p.command()
              << ": --only: limbs, laws, sphere, kidney, organ-twist, pad or patch\n";
    return 2;
  }
  std::vector<SceneOut> scenes = RunParts(cfg, only);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  const std::string csv = (std::filesystem::path(dir) / "speed-vs-error.csv").string();
  if (Status s = WriteCsv(csv, scenes); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().message << "\n";
    return 1;
  }
  if (Status s = WriteFigures(dir, scenes); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().message << "\n";
    return 1;
  }
  const std::string command =
      std::string("build/bin/vsurg-bench speed-vs-error") + (cfg.quick ? " --quick" : "") +
      (only.empty() ? "" : " --only " + only) + (dir == "docs" ? "" : " --out " + dir);
  const std::vector<study::BudgetVerdict> verdicts = study::CheckSceneBudgets(scenes);
  const std::string table = MarkdownTable(scenes, command) + study::BudgetTable(verdicts);
  std::string bench_md = p.Has("benchmarks") ? p.String("benchmarks") : "";
  if (!only.empty()) bench_md.clear();
  if (bench_md.empty() && only.empty() && std::filesystem::path(dir).filename() == "docs")
    bench_md = (std::filesystem::path(dir) / "BENCHMARKS.md").string();
  if (!bench_md.empty()) {
    if (Status s = UpdateBenchmarks(bench_md, table); !s.ok())
      std::cerr << p.command() << ": " << s.error().message << "\n";
  }
  std::cout << table;
  const int over = ReportOverBudget(p.command(), cfg, verdicts);
  std::cout << "speed-vs-error: " << Num(seconds, 3) << " s; wrote " << csv << ", "
            << (std::filesystem::path(dir) / "speed-vs-error.png").string() << ", "
            << (std::filesystem::path(dir) / "marker8.png").string()
            << (bench_md.empty() ? "" : ", " + bench_md) << "\n";
  return over > 0 && !cfg.quick ? 3 : 0;
}

}  // namespace vsurg::bench
