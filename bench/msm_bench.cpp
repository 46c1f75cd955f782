// Mass-spring micro-benchmarks: time per step of each integrator on
// the 258- and 1026-particle spheres (the mass-spring paper's "256" and "1024") and the default
// arm, and the coil model's update on the same arm torsion, side by side in one run.
//
//   build/bin/vsurg-microbench --benchmark_filter='Msm|CoilDeformArm/207'
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true   (one line)
#include <benchmark/benchmark.h>

#include <string>

#include "bench/msm_scenes.h"

namespace {

using vsurg::tissue::Integrator;

void BM_MsmStep(benchmark::State& state) {
  const Integrator integrator = vsurg::tissue::kAllIntegrators[state.range(0)];
  vsurg::bench::MsmScene s =
      vsurg::bench::MakeMsmScene(static_cast<int>(state.range(1)), integrator);
  long cg = 0, steps = 0;
  for (auto _ : state) {
    s.model.Step(vsurg::bench::kMsmDt);
    cg += s.model.last_cg_iterations();
    ++steps;
  }
  state.SetLabel(std::string(vsurg::tissue::IntegratorName(integrator)) + " " +
                 vsurg::bench::MsmSceneName(static_cast<int>(state.range(1))));
  state.counters["particles"] = static_cast<double>(s.model.positions().size());
  state.counters["springs"] = static_cast<double>(s.model.system().springs.size());
  state.counters["diverged"] = s.model.diverged();
  if (integrator == Integrator::kImplicitEuler)
    state.counters["cg_iterations"] = static_cast<double>(cg) / steps;
}
BENCHMARK(BM_MsmStep)->ArgsProduct({{0, 1, 2, 3, 4, 5}, {0, 1, 2}})->Unit(benchmark::kMicrosecond);

}  // namespace
