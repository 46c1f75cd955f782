// The implicit mass-spring step of bench/msm_scenes.h on its own: the median µs per step on the
// 1026-particle sphere and the 6182-particle arm, one line each ("sphere1026 32.1"). Not built by
// CMake: bench/msm_at_commits.sh compiles it against each commit's sources, so that the step's
// code can be compared across commits side by side in one run, without the rest of the build.
//   usage: msm_standalone [STEPS]   (default 2000)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "bench/msm_scenes.h"

int main(int argc, char** argv) {
  const int steps = argc > 1 ? std::atoi(argv[1]) : 2000;
  if (steps < 10) return 2;
  for (int which : {1, 2}) {
    auto s = vsurg::bench::MakeMsmScene(which, vsurg::tissue::Integrator::kImplicitEuler, 1e-3);
    std::vector<double> us;
    us.reserve(static_cast<size_t>(steps));
    for (int k = 0; k < steps; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      s.model.Step(vsurg::bench::kMsmDt);
      us.push_back(
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(us.begin(), us.end());
    std::printf("%s %.2f\n", vsurg::bench::MsmSceneName(which), us[us.size() / 2]);
  }
  return 0;
}
