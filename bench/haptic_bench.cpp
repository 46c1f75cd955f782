// Haptic path micro-benchmarks: the proxy, the grasp and the scenes' stylus path.
//
// BM_HapticPath: stylus sample in → force command out through Simulation::OnStylus, with the
// scene's deformation thread running in parallel on the other core. The trajectory is the good
// scripted trainee, replayed in a loop (grasp, twist, hold, release; or press and hold), so the
// deformation thread is busy publishing new surfaces while the haptic path reads them. Each call
// is timed on its own; the counters are the median and the 99th and 99.9th percentiles (µs), and
// how many surfaces the deformation thread published meanwhile. The second argument is the
// contact's local model (sim::HapticsSpec::ContactModel: 0 the tissue's viscoelastic, the default;
// 2 the proxy's spring alone): the sphere runs both, alternating, to show what the fit costs.
//
// The needle scene (argument 3) answers from its needle model instead of the proxy.
//
// BM_NeedleStep: the needle model alone (haptics/needle.h), one step of the good trainee's
// insertion into the vein (through skin, fat, muscle and the vein's wall, and back out), in a loop.
//
// BM_RingLayerStep vs BM_MsmStep/5/1: the same palpation of the 1026-particle sphere by the
// ring-layer model (only the rings around the contact move) and by the full mass-spring model.
//
// BM_BvhRefit: the deformation thread's refit of the surface's bounding boxes, once per published
// surface (Simulation::Publish), on the arm's and the organ's physics surfaces, every vertex moved.
//
// BM_BvhClosest: the haptic answer's surface query (ProxyContact::Update in contact): the closest
// point, among faces facing the contact's way, to a tip 3 mm under the surface, started from the
// proxy's face, over the arm's and the organ's physics surfaces. The second argument is how many
// sessions' surfaces the queries cycle through (each its own tree and positions, as each session
// has): 1 keeps one tree in cache; 64 is a node at 64 stations, where each session's tree and
// surface have left the cache by its next sample, and a query's cost is its memory reads.
//
//   build/bin/vsurg-microbench
//   --benchmark_filter='HapticPath|RingLayer|BvhRefit|BvhClosest|ProxyQuery'
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "common/geometry/bvh.h"
#include "common/geometry/mesh_generators.h"
#include "common/haptics/needle.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/tissue/ring_layer.h"

namespace {

void BM_HapticPath(benchmark::State& state) {
  static const char* kScenes[] = {"arm-torsion", "sphere-palpation-1024", "organ-surface-twist",
                                  "needle-vessel"};
  const char* name = kScenes[state.range(0)];
  auto scene = vsurg::sim::LoadSceneByName(name);
  if (scene.ok())
    scene->haptics.contact_model =
        static_cast<vsurg::sim::HapticsSpec::ContactModel>(state.range(1));
  auto samples = vsurg::sim::ScriptedTrainee(*scene, vsurg::sim::TraineeStyle::kGood);
  auto sim = vsurg::sim::Simulation::Create(*scene, {true});
  if (!scene.ok() || !samples.ok() || !sim.ok()) {
    state.SkipWithError("scene set-up failed");
    return;
  }
  // 20 000 calls paced 100 µs apart (10 kHz of wall time, 2 s): the deformation thread keeps
  // publishing while the haptic path runs; sample times advance 1 ms per call as at 1 kHz.
  constexpr int kCalls = 20000;
  const auto period = std::chrono::microseconds(100);
  std::vector<double> us;
  us.reserve(kCalls);
  double time_offset = 0;
  const double span = samples->back().time + 1e-3;
  for (auto _ : state) {
    auto next = std::chrono::steady_clock::now();
    for (int i = 0; i < kCalls; ++i) {
      next += period;
      while (std::chrono::steady_clock::now() < next) {
      }
      vsurg::haptics::StylusSample s = (*samples)[i % samples->size()];
      s.time += time_offset + span * static_cast<double>(i / samples->size());
      const auto t0 = std::chrono::steady_clock::now();
      const vsurg::haptics::ForceCommand c = (*sim)->OnStylus(s);
      const auto t1 = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(c);
      us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    }
  }
  std::sort(us.begin(), us.end());
  state.counters["p50_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[us.size() * 99 / 100];
  state.counters["p999_us"] = us[us.size() * 999 / 1000];
  state.counters["deform_updates"] = static_cast<double>((*sim)->deformation_updates());
  state.SetLabel(std::string(name) + (state.range(1) == 0 ? " viscoelastic" : " proxy"));
}
BENCHMARK(BM_HapticPath)
    ->Args({0, 0})
    ->Args({1, 0})
    ->Args({1, 2})
    ->Args({1, 0})
    ->Args({1, 2})
    ->Args({1, 0})
    ->Args({1, 2})
    ->Args({2, 0})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->Args({3, 0});

void BM_RingLayerStep(benchmark::State& state) {
  auto mesh =
      vsurg::geometry::MakeSubdividedSphere({0.05, 4, vsurg::geometry::SphereBase::kOctahedron});
  const vsurg::geometry::Vec3 contact = mesh->positions[4];
  std::vector<double> rho(mesh->VertexCount()),
      mass(mesh->VertexCount(), 0.55 / mesh->VertexCount());
  for (int v = 0; v < mesh->VertexCount(); ++v) rho[v] = (mesh->positions[v] - contact).norm();
  vsurg::tissue::RingLayerParams p;
  p.ring_spacing = 0.008;
  p.rings = 6;
  p.chain_stiffness = 40;
  p.tether_stiffness = 0.5;
  auto ring =
      vsurg::tissue::RingLayerModel::Create(mesh->positions, rho, mass, -contact.normalized(), p);
  ring->SetContactForce(0.2);
  int moved = 0;
  for (auto _ : state) {
    ring->Step(2e-4);
    moved = ring->Apply();
    benchmark::DoNotOptimize(ring->positions().data());
  }
  state.counters["moved_vertices"] = moved;
}
void BM_NeedleStep(benchmark::State& state) {
  auto scene = vsurg::sim::LoadSceneByName("needle-vessel");
  if (!scene.ok() || !scene->needle) return state.SkipWithError("needle-vessel did not load");
  auto samples = vsurg::sim::ScriptedTrainee(*scene, vsurg::sim::TraineeStyle::kGood);
  auto model = vsurg::haptics::NeedleModel::Create(*scene->needle);
  if (!samples.ok() || !model.ok()) return state.SkipWithError("set-up failed");
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(model->Step((*samples)[k].position, down, 1e-3));
    if (++k == samples->size()) k = 0;
  }
  state.counters["punctures"] = static_cast<double>(model->punctures());
}
BENCHMARK(BM_NeedleStep)->Unit(benchmark::kNanosecond);

BENCHMARK(BM_RingLayerStep)->Unit(benchmark::kMicrosecond);

// The physics surface of the arm (0) or the organ (1) scene, or an error the caller skips with.
const char* SceneSurfaceName(int64_t which) {
  return which == 0 ? "arm-torsion" : "organ-surface-twist";
}
vsurg::Expected<vsurg::sim::SceneMesh> SceneSurface(int64_t which) {
  auto scene = vsurg::sim::LoadSceneByName(SceneSurfaceName(which));
  if (!scene.ok()) return scene.error();
  return vsurg::sim::BuildSceneMesh(scene->mesh);
}

void BM_BvhRefit(benchmark::State& state) {
  const char* name = SceneSurfaceName(state.range(0));
  auto mesh = SceneSurface(state.range(0));
  if (!mesh.ok()) {
    state.SkipWithError("scene set-up failed");
    return;
  }
  vsurg::geometry::Bvh bvh(mesh->surface);
  // Two surfaces a millimetre apart, alternated, so every box changes on every refit.
  std::vector<vsurg::geometry::Vec3> a = mesh->surface.positions, b = a;
  for (auto& p : b) p += vsurg::geometry::Vec3(1e-3, -5e-4, 2e-4);
  bool flip = false;
  for (auto _ : state) {
    bvh.Refit(flip ? b : a);
    flip = !flip;
    benchmark::ClobberMemory();
  }
  state.counters["triangles"] = static_cast<double>(mesh->surface.TriangleCount());
  state.SetLabel(name);
}
BENCHMARK(BM_BvhRefit)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_BvhClosest(benchmark::State& state) {
  const char* name = SceneSurfaceName(state.range(0));
  const int sessions = static_cast<int>(state.range(1));
  auto mesh = SceneSurface(state.range(0));
  if (!mesh.ok()) {
    state.SkipWithError("scene set-up failed");
    return;
  }
  using vsurg::geometry::Vec3;
  const vsurg::geometry::TriMesh& surface = mesh->surface;
  // Each session's own tree and positions (copies, apart in memory as sessions' are).
  std::vector<vsurg::geometry::Bvh> trees(sessions, vsurg::geometry::Bvh(surface));
  std::vector<std::vector<Vec3>> positions(sessions, surface.positions);
  // The tips: 3 mm under the centre of every 7th face, each with its face as the proxy's.
  struct Tip {
    Vec3 p, normal;
    int triangle;
  };
  std::vector<Tip> tips;
  for (int t = 0; t < surface.TriangleCount(); t += 7) {
    const auto& tri = surface.triangles[t];
    const Vec3 n = vsurg::geometry::TriangleNormal(surface.positions, tri);
    const Vec3 c =
        (surface.positions[tri[0]] + surface.positions[tri[1]] + surface.positions[tri[2]]) / 3.0;
    if (n.allFinite()) tips.push_back({c - 0.003 * n, n, t});
  }
  if (tips.empty()) {
    state.SkipWithError("no face with a normal");
    return;
  }
  size_t i = 0;
  double found = 0;
  for (auto _ : state) {
    const Tip& tip = tips[i % tips.size()];
    const int s = static_cast<int>(i % static_cast<size_t>(sessions));
    const vsurg::geometry::ClosestHit hit =
        trees[s].Closest(positions[s], tip.p, 0.013, tip.normal, 0.0, tip.triangle);
    found += hit.triangle >= 0;
    benchmark::DoNotOptimize(hit);
    ++i;
  }
  state.counters["found"] = found / static_cast<double>(std::max<size_t>(i, 1));
  state.counters["triangles"] = static_cast<double>(surface.TriangleCount());
  state.SetLabel(name);
}
BENCHMARK(BM_BvhClosest)->ArgsProduct({{0, 1}, {1, 64}})->Unit(benchmark::kNanosecond);

// BM_ProxyQuery: the same query as a stylus moves (a 6 mm circle at 1 Hz, 3 mm under the
// surface, one query a millisecond, the last answer as the start), from the tree (third argument
// 0) or from the proxy's kept list (geometry::ClosestCache, 1 mm margin). The fourth argument is
// the surface's motion per query in µm as its snapshots would report it (0: still tissue; 20:
// 2 cm/s everywhere, a brisk twist), which makes the list be made again sooner; the fifth the
// list's margin in µm (the proxy's: 500, ProxyContact::kKeptListMargin).
void BM_ProxyQuery(benchmark::State& state) {
  const char* name = SceneSurfaceName(state.range(0));
  const int sessions = static_cast<int>(state.range(1));
  const bool kept = state.range(2) != 0;
  const double motion_step = 1e-6 * static_cast<double>(state.range(3));
  auto mesh = SceneSurface(state.range(0));
  if (!mesh.ok()) {
    state.SkipWithError("scene set-up failed");
    return;
  }
  using vsurg::geometry::Vec3;
  const vsurg::geometry::TriMesh& surface = mesh->surface;
  std::vector<vsurg::geometry::Bvh> trees(sessions, vsurg::geometry::Bvh(surface));
  std::vector<std::vector<Vec3>> positions(sessions, surface.positions);
  const double margin = 1e-6 * static_cast<double>(state.range(4));
  std::vector<vsurg::geometry::ClosestCache> caches(sessions,
                                                    vsurg::geometry::ClosestCache(margin));
  // Each session circles under its own face (spread over the surface), from its face's normal.
  struct Walk {
    Vec3 centre, normal, e1, e2;
    int last;
  };
  std::vector<Walk> walks;
  for (int s = 0; s < sessions; ++s) {
    const int t = static_cast<int>((static_cast<long>(s) * 7919 + 13) % surface.TriangleCount());
    const auto& tri = surface.triangles[t];
    const Vec3 n = vsurg::geometry::TriangleNormal(surface.positions, tri);
    if (!n.allFinite()) continue;
    const Vec3 c =
        (surface.positions[tri[0]] + surface.positions[tri[1]] + surface.positions[tri[2]]) / 3.0;
    const Vec3 e1 = n.unitOrthogonal();
    walks.push_back({c - 0.003 * n, n, e1, n.cross(e1), t});
  }
  if (walks.size() != static_cast<size_t>(sessions)) {
    state.SkipWithError("a face with no normal");
    return;
  }
  size_t i = 0;
  double found = 0, motion = 0;
  for (auto _ : state) {
    const int s = static_cast<int>(i % static_cast<size_t>(sessions));
    const double a = 2 * 3.141592653589793 * 1e-3 * static_cast<double>(i / sessions);
    Walk& w = walks[s];
    const Vec3 p = w.centre + 0.003 * (std::cos(a) * w.e1 + std::sin(a) * w.e2);
    if (s == 0) motion += motion_step;
    const vsurg::geometry::ClosestHit hit =
        kept ? caches[s].Closest(trees[s], positions[s], motion, p, 0.013, w.normal, 0.0, w.last)
             : trees[s].Closest(positions[s], p, 0.013, w.normal, 0.0, w.last);
    if (hit.triangle >= 0) w.last = hit.triangle;
    found += hit.triangle >= 0;
    benchmark::DoNotOptimize(hit);
    ++i;
  }
  double hits = 0, calls = 0, examined = 0;
  for (const auto& c : caches) {
    hits += static_cast<double>(c.hits()), calls += static_cast<double>(c.hits() + c.misses());
    examined += static_cast<double>(c.examined());
  }
  state.counters["found"] = found / static_cast<double>(std::max<size_t>(i, 1));
  state.counters["from_list"] = calls > 0 ? hits / calls : 0;
  double listed = 0;
  for (const auto& c : caches) listed += static_cast<double>(c.listed());
  state.counters["listed"] = listed / static_cast<double>(sessions);
  // Faces a list's answer measured, on average (the rest of its list could not be nearer).
  state.counters["examined"] = hits > 0 ? examined / hits : 0;
  state.SetLabel(std::string(name) + (kept ? " kept list" : " tree"));
}
BENCHMARK(BM_ProxyQuery)
    ->ArgsProduct({{0, 1}, {1, 64}, {0, 1}, {0}, {1000}})
    ->ArgsProduct({{0, 1}, {64}, {1}, {0, 20}, {250, 500, 2000}})
    ->Args({0, 64, 1, 20, 1000})
    ->Args({1, 64, 1, 20, 1000})
    ->Args({0, 64, 1, 0, 1})  // a 1 µm margin: every call walks the tree and lists again
    ->Args({1, 64, 1, 0, 1})
    ->Unit(benchmark::kNanosecond);

}  // namespace
