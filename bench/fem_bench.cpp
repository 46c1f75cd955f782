// FEM micro-benchmarks (issue: FEM reference): one corotational implicit Euler step (h = 1 ms,
// warm-started block-Jacobi CG, tolerance 1e-4) on a twisted bar of 5760 and 11250 tetrahedra —
// the sizes VegaFEM reports 64 ms and 158 ms per step for — and the coil deformation of the
// default arm in the same run.
//
//   build/bin/vsurg-microbench --benchmark_filter='FemStep|CoilDeformArm/207'
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true   (one line)
#include <benchmark/benchmark.h>

#include "common/geometry/tet_generators.h"
#include "common/tissue/fem.h"

namespace {

// rings 4 / 20 layers: 5760 tets; rings 5 / 25 layers: 11250 tets (bar 20 cm × 2 cm radius).
void BM_FemStep(benchmark::State& state) {
  const int rings = static_cast<int>(state.range(0));
  auto bar = vsurg::geometry::MakeTetCylinder({0.2, 0.02, 0.02, rings, 5 * rings});
  vsurg::tissue::FemParams p;
  auto fem = vsurg::tissue::FemModel::Create(bar->mesh, p, bar->base);
  const auto f =
      vsurg::tissue::TorqueNodalForces(bar->mesh.positions, bar->tip, bar->tip_area,
                                       Eigen::Vector3d(0, 0, 0.2), Eigen::Vector3d::UnitZ(), 2e-3);
  for (size_t i = 0; i < f.size(); ++i) fem->SetExternalForce(bar->tip[i], f[i]);
  for (int k = 0; k < 20; ++k) fem->StepImplicit(1e-3);  // in motion, warm start established
  int iterations = 0, steps = 0;
  for (auto _ : state) {
    const auto s = fem->StepImplicit(1e-3);
    iterations += s.cg_iterations;
    ++steps;
  }
  state.counters["tets"] = fem->TetCount();
  state.counters["cg_iterations"] = static_cast<double>(iterations) / std::max(1, steps);
}
BENCHMARK(BM_FemStep)->Arg(4)->Arg(5)->Unit(benchmark::kMillisecond);

}  // namespace
