// vsurg-bench hyper-step: one implicit-Euler step of the neo-Hookean FEM (tissue::HyperelasticFem
// with a density) on fem-step's bar, twisted harder (20 mN·m: a tenth of a turn at the tip, past
// the linear range), timed over --steps steps after 20 in motion; the bar written out for a peer
// (bench/peers/hyper.sh: VegaFEM's neo-Hookean backward Euler on the same files).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "bench/fem_step_command.h"
#include "common/core/args.h"
#include "common/tissue/hyperelastic.h"

namespace vsurg::bench {
namespace {

constexpr double kDt = 1e-3;       // s
constexpr double kTorque = 20e-3;  // N·m

struct Timing {
  std::vector<double> ms;
  long newton = 0;
  bool converged = true;
};

// 20 steps to set the bar in motion, then `steps` timed.
Timing Run(tissue::HyperelasticFem& fem, int steps, double tolerance) {
  Timing t;
  for (int k = 0; k < 20; ++k) t.converged &= fem.Step(kDt, tolerance).converged;
  t.ms.reserve(steps);
  for (int k = 0; k < steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const tissue::HyperelasticSolve s = fem.Step(kDt, tolerance);
    t.ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    t.newton += s.iterations;
    t.converged &= s.converged;
  }
  std::sort(t.ms.begin(), t.ms.end());
  return t;
}

}  // namespace

int HyperStep(const std::vector<std::string>& args) {
  cli::ArgParser p("vsurg-bench hyper-step",
                   "One implicit-Euler step of the neo-Hookean FEM (h = 1 ms, Newton to the "
                   "tolerance, no damping) on fem-step's bar under 20 mN*m, timed over --steps "
                   "steps after 20 in motion.");
  p.Option("rings", cli::ArgParser::Kind::kInt, "rings of the bar (4: 5760 tets, 5: 11250)", false,
           "4")
      .Option("steps", cli::ArgParser::Kind::kInt, "timed steps", false, "20")
      .Option("tolerance", cli::ArgParser::Kind::kDouble,
              "Newton's: the free forces' largest over the largest load", false, "1e-6")
      .Option("export", cli::ArgParser::Kind::kString,
              "write the bar, its fixed vertices, tip forces and settings into this folder for a "
              "peer (bench/peers/hyper.sh) and exit")
      .Option("json", cli::ArgParser::Kind::kFlag, "print one JSON object");
  BarRun run;
  if (auto rc = ParseBarRun(p, args, run)) return *rc;
  const int steps = run.steps;
  const double tolerance = run.tolerance;
  auto bar = MakeBar(run.rings, kTorque);
  if (!bar.ok()) return std::cerr << bar.error().message << "\n", 1;
  tissue::FemParams material;  // the tissue's E, ν and ρ; no damping (none in the hyperelastic)
  material.mass_damping = material.stiffness_damping = 0;
  if (p.Has("export")) {
    if (Status s = ExportBar(*bar, material, kDt, p.String("export")); !s.ok())
      return std::cerr << p.command() << ": " << s.error().message << "\n", 1;
    return 0;
  }
  auto fem = tissue::HyperelasticFem::Create(bar->cylinder.mesh,
                                             {material.young, material.poisson, 0, false});
  if (!fem.ok()) return std::cerr << fem.error().message << "\n", 1;
  if (Status s = fem->SetDensity(material.density); !s.ok())
    return std::cerr << s.error().message << "\n", 1;
  for (int v : bar->cylinder.base)
    for (int c = 0; c < 3; ++c) fem->Hold(v, c, bar->cylinder.mesh.positions[v][c]);
  for (size_t i = 0; i < bar->tip_forces.size(); ++i)
    fem->SetExternalForce(bar->cylinder.tip[i], bar->tip_forces[i]);
  const Timing t = Run(*fem, steps, tolerance);
  // A check that both sides move the bar alike: the largest displacement from rest, m.
  double moved = 0;
  for (size_t v = 0; v < fem->positions().size(); ++v)
    moved = std::max(moved,
                     (fem->positions()[v] - bar->cylinder.mesh.positions[v]).cwiseAbs().maxCoeff());
  const nlohmann::json j = {{"who", "vsurg"},
                            {"tets", bar->cylinder.mesh.TetCount()},
                            {"steps", steps},
                            {"tolerance", tolerance},
                            {"ms_median", t.ms[t.ms.size() / 2]},
                            {"ms_min", t.ms.front()},
                            {"newton_iterations", static_cast<double>(t.newton) / steps},
                            {"converged", t.converged},
                            {"max_displacement_m", moved}};
  if (p.Flag("json")) {
    std::cout << j.dump() << "\n";
  } else {
    std::printf(
        "vsurg: %d tets, %.3f ms per step (median of %d), %.2f Newton iterations, "
        "tolerance %g, largest displacement %.4f mm%s\n",
        bar->cylinder.mesh.TetCount(), t.ms[t.ms.size() / 2], steps,
        static_cast<double>(t.newton) / steps, tolerance, moved * 1e3,
        t.converged ? "" : " (a step did not converge)");
  }
  return t.converged ? 0 : 1;
}

}  // namespace vsurg::bench
