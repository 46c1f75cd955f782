// VegaFEM's side of bench/peers/hyper.sh: one implicit backward-Euler step of its neo-Hookean
// FEM (IsotropicHyperelasticFEM with NeoHookeanIsotropicMaterial: the same energy as vsurg's,
// μ/2·(I1 − 3) − μ·ln J + λ/2·(ln J)², no inversion clamp), Newton until the residual is EPS of
// the step's first (Vega's own criterion), each Newton system by Vega's Jacobi-preconditioned CG
// to 1e-6 (fixed in its source), on the bar `vsurg-bench hyper-step --export DIR` wrote: the same
// mesh, material, fixed base, tip forces and time step, no damping.
// Our harness code, built against a VegaFEM build outside this repository (CMakeLists.txt here).
//
//   vega_hyper_step DIR [STEPS] [EPS]  → one JSON line: ms per step (median, min) over STEPS
//                                        after 20
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "generateMassMatrix.h"
#include "implicitBackwardEulerSparse.h"
#include "isotropicHyperelasticFEM.h"
#include "isotropicHyperelasticFEMForceModel.h"
#include "neoHookeanIsotropicMaterial.h"
#include "tetMesh.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vega_hyper_step DIR [STEPS] [EPS]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int steps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 20;
  const double eps = argc > 3 ? std::atof(argv[3]) : 1e-6;
  std::map<std::string, double> settings;
  {
    std::ifstream in(dir + "/settings.txt");
    std::string key;
    double value;
    while (in >> key >> value) settings[key] = value;
  }
  for (const char* key : {"dt", "mass_damping", "stiffness_damping"}) {
    if (!settings.count(key)) {
      std::fprintf(stderr, "vega_hyper_step: %s/settings.txt has no %s\n", dir.c_str(), key);
      return 1;
    }
  }
  TetMesh mesh((dir + "/mesh.veg").c_str(), TetMesh::ASCII, 0);
  const int n = mesh.getNumVertices();
  std::vector<int> constrained;
  {
    std::ifstream in(dir + "/fixed.txt");
    int v;
    while (in >> v)
      for (int k = 0; k < 3; ++k) constrained.push_back(3 * v + k);
  }
  std::sort(constrained.begin(), constrained.end());  // Vega wants them ascending
  std::vector<double> forces(3 * n, 0.0);
  {
    std::ifstream in(dir + "/forces.txt");
    int v;
    double fx, fy, fz;
    while (in >> v >> fx >> fy >> fz)
      forces[3 * v] = fx, forces[3 * v + 1] = fy, forces[3 * v + 2] = fz;
  }
  SparseMatrix* mass = nullptr;
  GenerateMassMatrix::computeMassMatrix(&mesh, &mass, true);
  NeoHookeanIsotropicMaterial material(&mesh);
  IsotropicHyperelasticFEM fem(&mesh, &material);
  IsotropicHyperelasticFEMForceModel model(&fem);
  ImplicitBackwardEulerSparse integrator(
      3 * n, settings["dt"], mass, &model, static_cast<int>(constrained.size()), constrained.data(),
      settings["mass_damping"], settings["stiffness_damping"], 50 /* Newton's limit */, eps);
  integrator.SetExternalForces(forces.data());
  for (int k = 0; k < 20; ++k) integrator.DoTimestep();  // in motion, as ours
  std::vector<double> ms;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    integrator.DoTimestep();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  std::vector<double> q(3 * n);
  integrator.GetqState(q.data());
  double moved = 0;  // a check that both sides move the bar alike: the largest displacement, m
  for (double x : q) moved = std::max(moved, std::abs(x));
  std::printf(
      "{\"who\": \"vegafem\", \"tets\": %d, \"steps\": %d, \"eps\": %g, \"ms_median\": %.4f, "
      "\"ms_min\": %.4f, \"max_displacement_m\": %.6g}\n",
      mesh.getNumElements(), steps, eps, ms[ms.size() / 2], ms.front(), moved);
  delete mass;
  return 0;
}
