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
#include <cstdio>
#include <cstdlib>
#include <string>

#include "generateMassMatrix.h"
#include "implicitBackwardEulerSparse.h"
#include "isotropicHyperelasticFEM.h"
#include "isotropicHyperelasticFEMForceModel.h"
#include "neoHookeanIsotropicMaterial.h"
#include "tetMesh.h"
#include "vega_bar.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: vega_hyper_step DIR [STEPS] [EPS]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int steps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 20;
  const double eps = argc > 3 ? std::atof(argv[3]) : 1e-6;
  TetMesh mesh((dir + "/mesh.veg").c_str(), TetMesh::ASCII, 0);
  const int n = mesh.getNumVertices();
  VegaBar bar;
  if (!ReadVegaBar(dir, n, "vega_hyper_step", bar)) return 1;
  SparseMatrix* mass = nullptr;
  GenerateMassMatrix::computeMassMatrix(&mesh, &mass, true);
  NeoHookeanIsotropicMaterial material(&mesh);
  IsotropicHyperelasticFEM fem(&mesh, &material);
  IsotropicHyperelasticFEMForceModel model(&fem);
  ImplicitBackwardEulerSparse integrator(
      3 * n, bar.settings["dt"], mass, &model, static_cast<int>(bar.constrained.size()),
      bar.constrained.data(), bar.settings["mass_damping"], bar.settings["stiffness_damping"],
      50 /* Newton's limit */, eps);
  integrator.SetExternalForces(bar.forces.data());
  const VegaTiming t = TimeVegaSteps(integrator, 3 * n, steps);
  std::printf(
      "{\"who\": \"vegafem\", \"tets\": %d, \"steps\": %d, \"eps\": %g, \"ms_median\": %.4f, "
      "\"ms_min\": %.4f, \"max_displacement_m\": %.6g}\n",
      mesh.getNumElements(), steps, eps, t.ms_median, t.ms_min, t.moved);
  delete mass;
  return 0;
}
