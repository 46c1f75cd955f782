// FEM micro-benchmarks: one corotational implicit Euler step (h = 1 ms,
// warm-started CG, symmetric block Gauss-Seidel, tolerance 1e-4) on a twisted bar of 5760 and 11250
// tetrahedra — the sizes VegaFEM reports 64 ms and 158 ms per step for — and the coil deformation
// of the default arm in the same run.
//
//   build/bin/vsurg-microbench --benchmark_filter='FemStep|CoilDeformArm/207'
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true   (one line)
//
// And the reduced tables' precomputation on organ-surface-twist's FEM ball (5 cm, held on its
// lower fifth) of 16 and 20 cells, under both fill-reducing orderings (0 nested dissection, the
// default; 1 minimum degree, the former): the sparse Cholesky, and 64 static loads (one batch of
// the table's grasps) solved one at a time (Solve, as the tables did), eight at a time on one
// thread and on two (SolveMany):
//
//   build/bin/vsurg-microbench --benchmark_filter='StaticFactor|StaticLoads'
#include <benchmark/benchmark.h>

#include <memory>
#include <vector>

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

struct Ball {
  vsurg::geometry::TetMesh mesh;
  std::vector<int> held;
};

Ball OrganBall(int cells) {
  Ball b;
  b.mesh = vsurg::geometry::MakeTetBall({0.05, cells}).value();
  for (int i = 0; i < b.mesh.VertexCount(); ++i)
    if (b.mesh.positions[i].z() < -0.03) b.held.push_back(i);  // the lower fifth
  return b;
}

vsurg::tissue::FemParams OrganTissue() {
  vsurg::tissue::FemParams p;
  p.poisson = 0.47;
  p.young = 2 * 12e3 * 1.47;
  return p;
}

vsurg::tissue::FillOrdering Ordering(int64_t arg) {
  return arg == 0 ? vsurg::tissue::FillOrdering::kNestedDissection
                  : vsurg::tissue::FillOrdering::kMinimumDegree;
}

// range(0): cells; range(1): the ordering.
void BM_StaticFactor(benchmark::State& state) {
  const Ball b = OrganBall(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    auto r = vsurg::tissue::FemStaticResponse::Create(b.mesh, OrganTissue(), b.held,
                                                      Ordering(state.range(1)));
    benchmark::DoNotOptimize(r.ok());
  }
  state.counters["vertices"] = b.mesh.VertexCount();
}
BENCHMARK(BM_StaticFactor)
    ->ArgsProduct({{16, 20}, {0, 1}})
    ->Unit(benchmark::kSecond)
    ->Iterations(2);

// range(0): cells; range(1): the ordering; range(2): 0 one at a time, 1 SolveMany on one thread,
// 2 on two.
void BM_StaticLoads(benchmark::State& state) {
  const Ball b = OrganBall(static_cast<int>(state.range(0)));
  auto r = vsurg::tissue::FemStaticResponse::Create(b.mesh, OrganTissue(), b.held,
                                                    Ordering(state.range(1)))
               .value();
  std::vector<std::vector<Eigen::Vector3d>> loads(64);
  for (size_t k = 0; k < loads.size(); ++k) {
    loads[k].assign(b.mesh.VertexCount(), Eigen::Vector3d::Zero());
    loads[k][(k * 7919) % b.mesh.VertexCount()] = Eigen::Vector3d(0.1, -0.2, 1.0);
  }
  const int mode = static_cast<int>(state.range(2));
  for (auto _ : state) {
    if (mode == 0) {
      for (const auto& f : loads) benchmark::DoNotOptimize(r.Solve(f).data());
    } else {
      benchmark::DoNotOptimize(r.SolveMany(loads, mode).data());
    }
  }
  state.counters["loads"] = static_cast<double>(loads.size());
}
BENCHMARK(BM_StaticLoads)
    ->ArgsProduct({{16, 20}, {0, 1}, {0, 1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

}  // namespace
