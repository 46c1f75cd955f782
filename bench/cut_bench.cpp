// Cutting's costs (common/tissue/cut_membrane.h, common/haptics/blade.h): the patch's implicit
// step at three lattice sizes, a cut's topology update per edge (node snapping, the two fans
// separated), and the blade's force step with a long cut behind it.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>

#include "common/haptics/blade.h"
#include "common/tissue/cut_membrane.h"

namespace {

using vsurg::tissue::CutMembrane;
using vsurg::tissue::CutMembraneParams;
using vsurg::tissue::Vec2;
using vsurg::tissue::Vec3;

CutMembrane Patch(int cells) {
  CutMembraneParams p;
  p.cells = cells;
  return std::move(*CutMembrane::Create(p));
}

// One 1 ms step of a patch with a 40 mm cut in it, pressed beside the cut by 0.5 N.
void BM_CutPatchStep(benchmark::State& state) {
  CutMembrane m = Patch(static_cast<int>(state.range(0)));
  m.Cut(Vec2(-0.02, 0.001), Vec2(0.02, 0.001));
  m.Load(Vec2(0.0, -0.004), Vec3(0, 0, -0.5));
  int iterations = 0, steps = 0;
  for (auto _ : state) {
    m.Step(1e-3);
    iterations += m.model().last_cg_iterations(), ++steps;
  }
  state.counters["particles"] = static_cast<double>(m.positions().size());
  state.counters["cg_iterations"] = static_cast<double>(iterations) / std::max(steps, 1);
}
BENCHMARK(BM_CutPatchStep)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMicrosecond);

// A straight cut across a fresh patch in the blade's 0.1 mm steps; the time per edge cut.
void BM_CutAcrossPatch(benchmark::State& state) {
  const int cells = static_cast<int>(state.range(0));
  size_t edges = 0;
  for (auto _ : state) {
    state.PauseTiming();
    CutMembrane m = Patch(cells);
    state.ResumeTiming();
    const Vec2 a(-0.035, -0.01), b(0.035, 0.012);
    const int n = 700;
    for (int i = 0; i < n; ++i)
      m.Cut(a + (b - a) * (i / double(n)), a + (b - a) * ((i + 1) / double(n)));
    edges += m.cut_edges().size();
  }
  state.counters["edges"] = static_cast<double>(edges) / static_cast<double>(state.iterations());
  state.counters["us_per_edge"] = benchmark::Counter(
      static_cast<double>(edges), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CutAcrossPatch)->Arg(24)->Arg(32)->Unit(benchmark::kMicrosecond);

// The blade's step back in its own slit after a whole 15 mm circle (its cut about 380 segments
// of at least 0.25 mm): every step looks at every segment for the nearest, and none grows.
void BM_BladeStepInALongCut(benchmark::State& state) {
  vsurg::haptics::BladeParams p;
  auto blade = vsurg::haptics::BladeModel::Create(p);
  const double r = 0.015;
  for (int i = 0; i < 20000 && !blade->through(); ++i) blade->Step(Vec3(r, 0, -1e-6 * i));
  const int n = 20000;
  const auto at = [r](double u) {
    const double a = 2 * std::numbers::pi * u;
    return Vec3(r * std::cos(a), r * std::sin(a), -1e-3);
  };
  for (int i = 0; i <= n; ++i) blade->Step(at(1.02 * i / n));
  const int segments = blade->segment_count();
  int i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(blade->Step(at(0.2 + 0.6 * (i++ % n) / n)));
  state.counters["segments"] = segments;
  state.counters["grown"] = blade->segment_count() - segments;
}
BENCHMARK(BM_BladeStepInALongCut)->Unit(benchmark::kNanosecond);

}  // namespace
