// What both FEM harnesses share: the bar `vsurg-bench fem-step --export` and `hyper-step --export`
// write (settings.txt: dt and the Rayleigh damping; fixed.txt: the base's vertices; forces.txt:
// the tip's forces), read for VegaFEM, and the timing of an integrator's steps. Our harness code.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "implicitBackwardEulerSparse.h"

struct VegaBar {
  std::map<std::string, double> settings;
  std::vector<int> constrained;  // the fixed vertices' coordinates, ascending as Vega wants them
  std::vector<double> forces;    // N, 3 per vertex
};

// False (and a line on stderr naming `who`) when settings.txt lacks a value.
inline bool ReadVegaBar(const std::string& dir, int vertices, const char* who, VegaBar& bar) {
  std::ifstream settings(dir + "/settings.txt");
  std::string key;
  double value;
  while (settings >> key >> value) bar.settings[key] = value;
  for (const char* needed : {"dt", "mass_damping", "stiffness_damping"}) {
    if (!bar.settings.count(needed)) {
      std::fprintf(stderr, "%s: %s/settings.txt has no %s\n", who, dir.c_str(), needed);
      return false;
    }
  }
  std::ifstream fixed(dir + "/fixed.txt");
  int v;
  while (fixed >> v)
    for (int k = 0; k < 3; ++k) bar.constrained.push_back(3 * v + k);
  std::sort(bar.constrained.begin(), bar.constrained.end());
  bar.forces.assign(3 * vertices, 0.0);
  std::ifstream forces(dir + "/forces.txt");
  double fx, fy, fz;
  while (forces >> v >> fx >> fy >> fz)
    bar.forces[3 * v] = fx, bar.forces[3 * v + 1] = fy, bar.forces[3 * v + 2] = fz;
  return true;
}

struct VegaTiming {
  double ms_median = 0, ms_min = 0;
  double moved = 0;  // m, the largest displacement after the run: both sides move the bar alike
};

// 20 steps to set the bar in motion (as ours), then `steps` timed.
inline VegaTiming TimeVegaSteps(ImplicitBackwardEulerSparse& integrator, int dofs, int steps) {
  for (int k = 0; k < 20; ++k) integrator.DoTimestep();
  std::vector<double> ms;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    integrator.DoTimestep();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  std::vector<double> q(dofs);
  integrator.GetqState(q.data());
  VegaTiming t{ms[ms.size() / 2], ms.front(), 0};
  for (double x : q) t.moved = std::max(t.moved, std::abs(x));
  return t;
}
