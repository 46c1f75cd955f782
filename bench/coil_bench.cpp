// Coil-spring model micro-benchmarks. Goals on the 2-core reference machine:
// a deformation update of the default arm for a new torque ≤ 20 µs; an inverse query ≤ 100 ns.
//
//   build/bin/vsurg-microbench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <random>

#include <Eigen/Geometry>
#include <vector>

#include "common/geometry/mesh_generators.h"
#include "common/sim/limb_scene.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"

namespace {

using vsurg::sim::BuiltinLimbScene;
using vsurg::sim::Instantiate;

// Torques cycling around a target so every iteration is a new torque (no caching possible).
std::vector<double> TorquesAround(double centre, double spread, int n) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(centre - spread, centre + spread);
  std::vector<double> t(n);
  for (double& x : t) x = u(rng);
  return t;
}

// The default arm (6182 vertices) twisted by about the coil-spring paper's 2.07 N·m: P ≈ 18, ~4900
// vertices move.
void BM_CoilDeformArm(benchmark::State& state) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  const double centre = static_cast<double>(state.range(0)) / 100.0;
  const std::vector<double> torques = TorquesAround(centre, 0.02, 1024);
  size_t k = 0;
  int moved = 0;
  for (auto _ : state) {
    const auto st = inst->deformer.Update(torques[k++ & 1023]);
    moved = st.moved_vertices;
    benchmark::DoNotOptimize(inst->deformer.positions().data());
  }
  state.counters["moved_vertices"] = moved;
  state.counters["vertices"] = inst->limb.surface.VertexCount();
}
BENCHMARK(BM_CoilDeformArm)->Arg(50)->Arg(207)->Arg(330)->Unit(benchmark::kMicrosecond);

// Baseline, side by side: what a direct implementation does per update — every vertex, its own
// angle, an Eigen axis–angle rotation about the limb axis. Same result as the deformer.
void BM_CoilDeformArmPerVertexBaseline(benchmark::State& state) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  const auto& rest = inst->limb.surface.positions;
  const auto& rho = inst->deformer.distances();
  std::vector<vsurg::geometry::Vec3> out(rest.size());
  auto st = inst->model.MakeState();
  const double centre = static_cast<double>(state.range(0)) / 100.0;
  const std::vector<double> torques = TorquesAround(centre, 0.02, 1024);
  size_t k = 0;
  for (auto _ : state) {
    inst->model.Forward(torques[k++ & 1023], st);
    for (size_t v = 0; v < rest.size(); ++v) {
      const double theta = inst->model.TwistAt(rho[v], st);
      const vsurg::geometry::Vec3 foot(0, 0, rest[v].z());
      out[v] = foot + Eigen::AngleAxisd(theta, vsurg::geometry::Vec3::UnitZ()) * (rest[v] - foot);
    }
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_CoilDeformArmPerVertexBaseline)
    ->Arg(50)
    ->Arg(207)
    ->Arg(330)
    ->Unit(benchmark::kMicrosecond);

// A new grasp's binding on the default arm, side by side: projecting every vertex onto the
// centreline at each grasp (Arg 0: CreateForLimb from the centreline) against the projections
// made once per scene (Arg 1: what the coil room and the station's twist view do).
void BM_CoilBindArm(benchmark::State& state) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  const auto& rest = inst->limb.surface.positions;
  const auto& centreline = inst->limb.centreline;
  const auto projection = vsurg::geometry::ProjectOntoPolyline(rest, centreline);
  const double length = vsurg::geometry::ArcLengths(centreline).back();
  const bool once = state.range(0) == 1;
  size_t k = 0;
  for (auto _ : state) {
    const double arc = length * (0.5 + 0.4 * static_cast<double>(k++ % 16) / 16);
    auto d = once ? vsurg::tissue::CoilDeformer::CreateForLimb(inst->model, rest, *projection,
                                                               length, arc)
                  : vsurg::tissue::CoilDeformer::CreateForLimb(inst->model, rest, centreline, arc);
    benchmark::DoNotOptimize(d->positions().data());
  }
  state.counters["vertices"] = static_cast<double>(rest.size());
  state.counters["centreline_points"] = static_cast<double>(centreline.size());
}
BENCHMARK(BM_CoilBindArm)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Surface mode on the 1026-vertex sphere (geodesic distances, one angle per vertex).
void BM_CoilDeformSphereSurface(benchmark::State& state) {
  auto sphere =
      vsurg::geometry::MakeSubdividedSphere({0.05, 4, vsurg::geometry::SphereBase::kOctahedron});
  auto grasp = vsurg::geometry::ClosestSurfacePoint(*sphere, vsurg::geometry::Vec3(0, 0, 1));
  vsurg::tissue::CoilSpringParams p;
  p.core_radius = 0.004;
  p.thickness = 0.004;
  p.coils = 20;
  p.width = 0.01;
  p.modulus = 1e9;
  p.max_force = 0.2;
  auto model = vsurg::tissue::CoilSpringModel::Create(p);
  auto def = vsurg::tissue::CoilDeformer::CreateForSurface(*model, *sphere, *grasp,
                                                           vsurg::geometry::GeodesicMethod::kHeat);
  const std::vector<double> torques =
      TorquesAround(0.5 * model->Capacity(), 0.05 * model->Capacity(), 1024);
  size_t k = 0;
  int moved = 0;
  for (auto _ : state) {
    moved = def->Update(torques[k++ & 1023]).moved_vertices;
    benchmark::DoNotOptimize(def->positions().data());
  }
  state.counters["moved_vertices"] = moved;
}
BENCHMARK(BM_CoilDeformSphereSurface)->Unit(benchmark::kMicrosecond);

// The haptic query: imposed twist → torque and stiffness, across all segments of the arm model.
void BM_CoilInverse(benchmark::State& state) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  const auto& m = inst->model;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.1 * m.TwistAtCapacity(), 1.1 * m.TwistAtCapacity());
  std::vector<double> twists(4096);
  for (double& x : twists) x = u(rng);
  size_t k = 0;
  for (auto _ : state) {
    const auto r = m.Inverse(twists[k++ & 4095]);
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_CoilInverse)->Unit(benchmark::kNanosecond);

// Forward evaluation (torque → all coils and boundary angles) into a prepared state.
void BM_CoilForward(benchmark::State& state) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  const auto& m = inst->model;
  auto st = m.MakeState();
  const std::vector<double> torques = TorquesAround(0, 3.5, 4096);
  size_t k = 0;
  for (auto _ : state) {
    m.Forward(torques[k++ & 4095], st);
    benchmark::DoNotOptimize(st.total_twist);
  }
}
BENCHMARK(BM_CoilForward)->Unit(benchmark::kNanosecond);

}  // namespace

BENCHMARK_MAIN();
