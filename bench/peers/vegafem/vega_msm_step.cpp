// VegaFEM's side of bench/peers/msm.sh: one implicit backward-Euler step (one Newton iteration,
// Vega's Jacobi-preconditioned CG to 1e-6, fixed in its source) of its mass-spring system, on a
// scene `vsurg-bench msm-step --export DIR` wrote: the same particles, masses, springs (k per
// spring; Vega keeps one k per material group, so one group per distinct k), rest shape, state
// after the drive's ramp, time step, and fixed and driven particles held (constrained DOFs).
// Vega's implicit integrator damps by Rayleigh damping only, not through the springs' dampers:
// β = c/k of the stiffest group gives its springs our damper's rate; the others get more.
// Our harness code, built against a VegaFEM checkout outside this repository (CMakeLists.txt).
//
//   vega_msm_step SCENE.msm [STEPS]   → one JSON line: µs per step (median, p90) over STEPS
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "implicitBackwardEulerSparse.h"
#include "massSpringSystem.h"
#include "massSpringSystemForceModel.h"
#include "sparseMatrix.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vega_msm_step SCENE.msm [STEPS]\n");
    return 2;
  }
  const int steps = argc > 2 ? std::max(10, std::atoi(argv[2])) : 2000;
  std::ifstream in(argv[1]);
  std::string word;
  double dt = 0;
  int n = 0, m = 0;
  in >> word >> dt >> word >> n;
  std::vector<double> x(3 * n), masses(n);
  std::vector<int> flags(n);
  for (int i = 0; i < n; ++i)
    in >> x[3 * i] >> x[3 * i + 1] >> x[3 * i + 2] >> masses[i] >> flags[i];
  in >> word >> m;
  std::vector<int> edges(2 * m), groups(m);
  std::map<double, int> group_of_k;  // k → group
  std::vector<double> group_k, group_c;
  for (int s = 0; s < m; ++s) {
    double k, c, rest;
    in >> edges[2 * s] >> edges[2 * s + 1] >> k >> c >> rest;
    auto [it, added] = group_of_k.emplace(k, static_cast<int>(group_k.size()));
    if (added) group_k.push_back(k), group_c.push_back(c);
    groups[s] = it->second;
  }
  int rest_count = 0;
  in >> word >> rest_count;
  if (!in || word != "rest" || rest_count != n) {
    std::fprintf(stderr, "vega_msm_step: %s has no rest section (vsurg-bench msm-step --export)\n",
                 argv[1]);
    return 1;
  }
  std::vector<double> rest(3 * n), q(3 * n), qvel(3 * n);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) in >> rest[3 * i + k];
    for (int k = 0; k < 3; ++k) in >> qvel[3 * i + k];
  }
  if (!in) {
    std::fprintf(stderr, "vega_msm_step: cannot read %s\n", argv[1]);
    return 1;
  }
  for (int k = 0; k < 3 * n; ++k) q[k] = x[k] - rest[k];
  std::vector<int> constrained;  // ascending, as Vega wants them
  for (int i = 0; i < n; ++i) {
    if (flags[i] != 0) {
      for (int k = 0; k < 3; ++k) constrained.push_back(3 * i + k), qvel[3 * i + k] = 0;
    }
  }
  const size_t stiffest = std::max_element(group_k.begin(), group_k.end()) - group_k.begin();
  const double beta = group_c[stiffest] / group_k[stiffest];

  MassSpringSystem system(n, masses.data(), rest.data(), m, edges.data(), groups.data(),
                          static_cast<int>(group_k.size()), group_k.data(), group_c.data(), 0);
  SparseMatrix* mass = nullptr;
  system.GenerateMassMatrix(&mass, 3);
  MassSpringSystemForceModel model(&system);
  ImplicitBackwardEulerSparse integrator(3 * n, dt, mass, &model,
                                         static_cast<int>(constrained.size()), constrained.data(),
                                         0.0, beta, 1 /* one Newton iteration */);
  integrator.SetState(q.data(), qvel.data());
  std::vector<double> us;
  us.reserve(steps);
  for (int k = 0; k < steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    integrator.DoTimestep();
    us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(us.begin(), us.end());
  integrator.GetqState(q.data());
  double moved = 0;  // a check that both sides hold the scene alike: the largest displacement, m
  for (int i = 0; i < n; ++i) {
    moved = std::max(moved, std::sqrt(q[3 * i] * q[3 * i] + q[3 * i + 1] * q[3 * i + 1] +
                                      q[3 * i + 2] * q[3 * i + 2]));
  }
  std::string scene = argv[1];
  scene = scene.substr(scene.find_last_of('/') + 1);
  scene = scene.substr(0, scene.find('.'));
  std::printf(
      "{\"who\":\"vegafem\",\"scene\":\"%s\",\"particles\":%d,\"springs\":%d,\"method\":"
      "\"implicit backward Euler, 1 Newton it., Jacobi PCG 1e-6, Rayleigh %.3g K\","
      "\"step_us_median\":%.3f,\"step_us_p90\":%.3f,\"max_displacement_m\":%.6g}\n",
      scene.c_str(), n, m, beta, us[us.size() / 2], us[us.size() * 9 / 10], moved);
  delete mass;
  return 0;
}
