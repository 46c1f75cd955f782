// Mass-spring micro-benchmarks (issue: mass-spring model): time per step of each integrator on
// the 258- and 1026-particle spheres (seed 001's "256" and "1024") and the default arm, and the
// coil model's update on the same arm torsion, side by side in one run.
//
//   build/bin/vsurg-microbench --benchmark_filter='Msm|CoilDeformArm/207'
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true   (one line)
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry/mesh_generators.h"
#include "common/tissue/mass_spring.h"

namespace {

using vsurg::geometry::Vec3;
using vsurg::tissue::Integrator;

constexpr double kDt = 2e-4;  // s: 5 kHz, the rate a haptic-rate deformation needs

// Scene 0, 1: sphere of 258 or 1026 particles, bottom fifth fixed, top pressed 5 mm.
// Scene 2: the default arm (6182 particles), elbow fixed, wrist ring turned by 60° (the coil
// scene's twist at 2.07 N·m).
struct Scene {
  vsurg::tissue::MassSpringModel model;
  std::vector<int> driven;
  std::vector<Vec3> target;
};

Scene MakeScene(int which, Integrator integrator) {
  vsurg::geometry::TriMesh mesh;
  if (which < 2) {
    mesh = *vsurg::geometry::MakeSubdividedSphere(
        {0.05, which == 0 ? 3 : 4, vsurg::geometry::SphereBase::kOctahedron});
  } else {
    mesh = vsurg::geometry::MakeLimb(vsurg::geometry::ForearmPreset())->surface;
  }
  vsurg::tissue::MassSpringBuildParams bp;
  bp.total_mass = 1050.0 * vsurg::geometry::SignedVolume(mesh);
  auto sys = vsurg::tissue::BuildMassSpring(mesh, bp);
  vsurg::tissue::MassSpringStepParams sp;
  sp.integrator = integrator;
  auto model = vsurg::tissue::MassSpringModel::Create(*sys, sp);
  Scene s{std::move(*model), {}, {}};
  const double length = which == 2 ? vsurg::geometry::ForearmPreset().length : 0;
  const Eigen::AngleAxisd twist(std::numbers::pi / 3, Vec3::UnitZ());
  for (int v = 0; v < mesh.VertexCount(); ++v) {
    const Vec3& p = mesh.positions[v];
    if (which < 2) {
      if (p.z() < -0.03) s.model.SetFixed(v, true);
      if (p.z() > 0.0499) s.driven.push_back(v), s.target.push_back(p - Vec3(0, 0, 0.005));
    } else {
      if (p.z() == 0.0) s.model.SetFixed(v, true);
      if (p.z() == length) s.driven.push_back(v), s.target.push_back(twist * p);
    }
  }
  for (int v : s.driven) s.model.SetKinematic(v, true);
  // Ramp the drive in over 200 steps, then time steps with it held.
  for (int k = 1; k <= 200; ++k) {
    for (size_t d = 0; d < s.driven.size(); ++d) {
      const Vec3 rest = s.model.system().rest_positions[s.driven[d]];
      s.model.SetKinematicTarget(s.driven[d], rest + (s.target[d] - rest) * (k / 200.0));
    }
    s.model.Step(kDt);
  }
  return s;
}

void BM_MsmStep(benchmark::State& state) {
  const Integrator integrator = vsurg::tissue::kAllIntegrators[state.range(0)];
  Scene s = MakeScene(static_cast<int>(state.range(1)), integrator);
  long cg = 0, steps = 0;
  for (auto _ : state) {
    s.model.Step(kDt);
    cg += s.model.last_cg_iterations();
    ++steps;
  }
  state.SetLabel(std::string(vsurg::tissue::IntegratorName(integrator)) +
                 (state.range(1) == 0   ? " sphere258"
                  : state.range(1) == 1 ? " sphere1026"
                                        : " arm6182"));
  state.counters["particles"] = static_cast<double>(s.model.positions().size());
  state.counters["springs"] = static_cast<double>(s.model.system().springs.size());
  state.counters["diverged"] = s.model.diverged();
  if (integrator == Integrator::kImplicitEuler)
    state.counters["cg_iterations"] = static_cast<double>(cg) / steps;
}
BENCHMARK(BM_MsmStep)->ArgsProduct({{0, 1, 2, 3, 4, 5}, {0, 1, 2}})->Unit(benchmark::kMicrosecond);

}  // namespace
