// PositionBasedDynamics on our mass-spring scenes (vsurg-bench msm-step --export): one XPBD step
// per dt, ITERATIONS (default 10) Gauss-Seidel sweeps of PBD's own
// XPBD::solve_DistanceConstraint over every spring, compliance 1/k (the spring's stiffness), as
// PBD's examples step a cloth or a tet mesh: predict, project, update velocities. Fixed and
// kinematic particles have inverse mass 0. Prints the median time per step as one JSON line.
//
//   pbd_step SCENE.msm [STEPS] [ITERATIONS]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "PositionBasedDynamics/XPBD.h"

int main(int argc, char** argv) {
  if (argc < 2) return std::cerr << "usage: pbd_step SCENE.msm [STEPS] [ITERATIONS]\n", 2;
  const int steps = argc > 2 ? std::stoi(argv[2]) : 2000;
  const int iterations = argc > 3 ? std::stoi(argv[3]) : 10;
  std::ifstream in(argv[1]);
  std::string word;
  Real dt = 0;
  size_t n = 0, m = 0;
  in >> word >> dt >> word >> n;
  std::vector<Vector3r> x(n), p(n), v(n, Vector3r::Zero());
  std::vector<Real> w(n);
  for (size_t i = 0; i < n; ++i) {
    Real mass;
    int flag;
    in >> x[i].x() >> x[i].y() >> x[i].z() >> mass >> flag;
    w[i] = flag == 0 ? 1 / mass : 0;
  }
  in >> word >> m;
  struct Spring {
    int i, j;
    Real k, c, rest;
  };
  std::vector<Spring> springs(m);
  for (auto& s : springs) in >> s.i >> s.j >> s.k >> s.c >> s.rest;
  if (!in) return std::cerr << "pbd_step: cannot read " << argv[1] << "\n", 1;
  std::vector<Real> lambda(m);
  std::vector<double> us;
  us.reserve(steps);
  for (int step = 0; step < steps; ++step) {
    const auto t0 = std::chrono::steady_clock::now();
    for (size_t i = 0; i < n; ++i) p[i] = x[i] + dt * v[i];
    std::fill(lambda.begin(), lambda.end(), 0);
    for (int it = 0; it < iterations; ++it) {
      for (size_t s = 0; s < m; ++s) {
        const Spring& k = springs[s];
        Vector3r c0, c1;
        if (PBD::XPBD::solve_DistanceConstraint(p[k.i], w[k.i], p[k.j], w[k.j], k.rest, k.k, dt,
                                                lambda[s], c0, c1)) {
          if (w[k.i] != 0) p[k.i] += c0;
          if (w[k.j] != 0) p[k.j] += c1;
        }
      }
    }
    for (size_t i = 0; i < n; ++i) {
      v[i] = (p[i] - x[i]) / dt;
      x[i] = p[i];
    }
    us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(us.begin(), us.end());
  std::string scene = argv[1];
  scene = scene.substr(scene.find_last_of('/') + 1);
  scene = scene.substr(0, scene.find('.'));
  std::printf(
      "{\"who\":\"pbd\",\"scene\":\"%s\",\"particles\":%zu,\"springs\":%zu,\"method\":\"XPBD, %d "
      "iterations\",\"step_us_median\":%.3f,\"step_us_p90\":%.3f}\n",
      scene.c_str(), n, m, iterations, us[us.size() / 2], us[us.size() * 9 / 10]);
  return 0;
}
