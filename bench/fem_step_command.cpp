#include "bench/fem_step_command.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "common/geometry/tet_generators.h"
#include "common/tissue/fem.h"

namespace vsurg::bench {

Expected<Bar> MakeBar(int rings, double torque) {
  auto c = geometry::MakeTetCylinder({0.2, 0.02, 0.02, rings, 5 * rings});
  if (!c.ok()) return c.error();
  Bar b{std::move(c).value(), {}};
  b.tip_forces =
      tissue::TorqueNodalForces(b.cylinder.mesh.positions, b.cylinder.tip, b.cylinder.tip_area,
                                Eigen::Vector3d(0, 0, 0.2), Eigen::Vector3d::UnitZ(), torque);
  return b;
}

Status ExportBar(const Bar& bar, const tissue::FemParams& p, double dt, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{ErrorCode::kIoError, "cannot create " + dir + ": " + ec.message(), "export"};
  const geometry::TetMesh& m = bar.cylinder.mesh;
  std::ofstream veg(dir + "/mesh.veg");
  veg.precision(17);
  veg << "# vsurg bar: " << m.VertexCount() << " vertices, " << m.TetCount() << " tetrahedra\n";
  veg << "*VERTICES\n" << m.VertexCount() << " 3 0 0\n";
  for (int v = 0; v < m.VertexCount(); ++v)
    veg << v + 1 << " " << m.positions[v].x() << " " << m.positions[v].y() << " "
        << m.positions[v].z() << "\n";
  veg << "*ELEMENTS\nTET\n" << m.TetCount() << " 4 0\n";
  for (int t = 0; t < m.TetCount(); ++t) {
    veg << t + 1;
    for (int k = 0; k < 4; ++k) veg << " " << m.tetrahedra[t][k] + 1;
    veg << "\n";
  }
  veg << "*MATERIAL BODY\nENU, " << p.density << ", " << p.young << ", " << p.poisson << "\n";
  veg << "*REGION\nallElements, BODY\n";
  std::ofstream fixed(dir + "/fixed.txt");
  for (int v : bar.cylinder.base) fixed << v << "\n";
  std::ofstream forces(dir + "/forces.txt");
  forces.precision(17);
  for (size_t i = 0; i < bar.cylinder.tip.size(); ++i)
    forces << bar.cylinder.tip[i] << " " << bar.tip_forces[i].x() << " " << bar.tip_forces[i].y()
           << " " << bar.tip_forces[i].z() << "\n";
  std::ofstream settings(dir + "/settings.txt");
  settings.precision(17);
  settings << "dt " << dt << "\nmass_damping " << p.mass_damping << "\nstiffness_damping "
           << p.stiffness_damping << "\n";
  if (!veg || !fixed || !forces || !settings)
    return Error{ErrorCode::kIoError, "cannot write the bar's files in " + dir, "export"};
  return Status::Ok();
}

std::optional<int> ParseBarRun(cli::ArgParser& p, const std::vector<std::string>& args,
                               BarRun& out) {
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  out = {p.Int("rings"), p.Int("steps"), p.Double("tolerance")};
  if (out.rings < 1 || out.rings > 12) return std::cerr << p.command() << ": --rings: 1..12\n", 2;
  if (out.steps < 1 || out.steps > 100000)
    return std::cerr << p.command() << ": --steps: 1..100000\n", 2;
  if (!(out.tolerance > 0 && out.tolerance < 1))
    return std::cerr << p.command() << ": --tolerance: must be in (0, 1)\n", 2;
  return std::nullopt;
}

int FemStep(const std::vector<std::string>& args) {
  cli::ArgParser p("vsurg-bench fem-step",
                   "One corotational implicit FEM step (h = 1 ms, one Newton step, CG "
                   "warm-started) on the twisted bar of BM_FemStep, timed over --steps steps "
                   "after 20 in motion.");
  p.Option("rings", cli::ArgParser::Kind::kInt, "rings of the bar (4: 5760 tets, 5: 11250)", false,
           "5")
      .Option("steps", cli::ArgParser::Kind::kInt, "timed steps", false, "50")
      .Option("tolerance", cli::ArgParser::Kind::kDouble, "CG relative residual", false, "1e-4")
      .Option("preconditioner", cli::ArgParser::Kind::kString,
              "the CG's preconditioner: gauss-seidel (symmetric block Gauss-Seidel) or jacobi "
              "(block Jacobi)",
              false, "gauss-seidel")
      .Option("export", cli::ArgParser::Kind::kString,
              "write the bar, its fixed vertices, tip forces and settings into this folder for a "
              "peer (bench/peers/fem.sh) and exit")
      .Option("json", cli::ArgParser::Kind::kFlag, "print one JSON object");
  BarRun run;
  if (auto rc = ParseBarRun(p, args, run)) return *rc;
  const int rings = run.rings, steps = run.steps;
  const double tolerance = run.tolerance;
  const std::string preconditioner = p.String("preconditioner");
  if (preconditioner != "gauss-seidel" && preconditioner != "jacobi")
    return std::cerr << p.command() << ": --preconditioner: gauss-seidel or jacobi\n", 2;
  auto bar = MakeBar(rings);
  if (!bar.ok()) return std::cerr << bar.error().message << "\n", 1;
  tissue::FemParams params;
  params.cg_tolerance = tolerance;
  params.preconditioner = preconditioner == "jacobi" ? tissue::Preconditioner::kBlockJacobi
                                                     : tissue::Preconditioner::kGaussSeidel;
  constexpr double kDt = 1e-3;
  if (p.Has("export")) {
    if (Status s = ExportBar(*bar, params, kDt, p.String("export")); !s.ok())
      return std::cerr << p.command() << ": " << s.error().message << "\n", 1;
    return 0;
  }
  auto fem = tissue::FemModel::Create(bar->cylinder.mesh, params, bar->cylinder.base);
  if (!fem.ok()) return std::cerr << fem.error().message << "\n", 1;
  for (size_t i = 0; i < bar->tip_forces.size(); ++i)
    fem->SetExternalForce(bar->cylinder.tip[i], bar->tip_forces[i]);
  for (int k = 0; k < 20; ++k) fem->StepImplicit(kDt);  // in motion, warm start established
  std::vector<double> ms;
  ms.reserve(steps);
  long iterations = 0;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const tissue::FemStepStats s = fem->StepImplicit(kDt);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    iterations += s.cg_iterations;
  }
  std::sort(ms.begin(), ms.end());
  // A check that both sides move the bar alike: the largest displacement from rest, m.
  double moved = 0;
  for (int v = 0; v < fem->VertexCount(); ++v)
    moved = std::max(moved, (fem->positions()[v] - fem->rest().positions[v]).cwiseAbs().maxCoeff());
  nlohmann::json j = {{"who", "vsurg"},
                      {"tets", fem->TetCount()},
                      {"steps", steps},
                      {"tolerance", tolerance},
                      {"preconditioner", preconditioner},
                      {"ms_median", ms[ms.size() / 2]},
                      {"ms_min", ms.front()},
                      {"cg_iterations", static_cast<double>(iterations) / steps},
                      {"max_displacement_m", moved}};
  if (p.Flag("json")) {
    std::cout << j.dump() << "\n";
  } else {
    std::printf(
        "vsurg: %d tets, %.3f ms per step (median of %d), %.1f CG iterations, tolerance %g, %s\n",
        fem->TetCount(), ms[ms.size() / 2], steps, static_cast<double>(iterations) / steps,
        tolerance, preconditioner.c_str());
  }
  return 0;
}

}  // namespace vsurg::bench
