// VegaFEM's side of bench/peers/fem.sh: one implicit backward-Euler step (one Newton iteration,
// Vega's Jacobi-preconditioned CG, which Vega runs to 1e-6 in its M⁻¹-weighted residual: fixed
// in its source) of its corotational linear FEM, on the bar `vsurg-bench fem-step --export DIR`
// wrote: the same mesh, material, fixed base, tip forces, time step and Rayleigh damping.
// Our harness code, built against a VegaFEM build outside this repository (CMakeLists.txt here).
//
//   vega_fem_step DIR [STEPS]   → one JSON line: ms per step (median, min) over STEPS after 20
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "corotationalLinearFEM.h"
#include "corotationalLinearFEMForceModel.h"
#include "generateMassMatrix.h"
#include "implicitBackwardEulerSparse.h"
#include "tetMesh.h"
#include "vega_bar.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vega_fem_step DIR [STEPS]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int steps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 50;
  TetMesh mesh((dir + "/mesh.veg").c_str(), TetMesh::ASCII, 0);
  const int n = mesh.getNumVertices();
  VegaBar bar;
  if (!ReadVegaBar(dir, n, "vega_fem_step", bar)) return 1;
  SparseMatrix* mass = nullptr;
  GenerateMassMatrix::computeMassMatrix(&mesh, &mass, true);
  CorotationalLinearFEM fem(&mesh);
  CorotationalLinearFEMForceModel model(&fem, 1);  // warp = 1: corotational
  ImplicitBackwardEulerSparse integrator(
      3 * n, bar.settings["dt"], mass, &model, static_cast<int>(bar.constrained.size()),
      bar.constrained.data(), bar.settings["mass_damping"], bar.settings["stiffness_damping"],
      1 /* one Newton iteration */);
  integrator.SetExternalForces(bar.forces.data());
  const VegaTiming t = TimeVegaSteps(integrator, 3 * n, steps);
  std::printf(
      "{\"who\": \"vegafem\", \"tets\": %d, \"steps\": %d, \"ms_median\": %.4f, "
      "\"ms_min\": %.4f, \"max_displacement_m\": %.6g}\n",
      mesh.getNumElements(), steps, t.ms_median, t.ms_min, t.moved);
  delete mass;
  return 0;
}
