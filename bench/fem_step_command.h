// vsurg-bench fem-step: one corotational implicit FEM step timed on the twisted bar of
// BM_FemStep, standalone so a script can alternate it with a peer's (bench/peers/fem.sh), and
// the bar written out as files the peer reads.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/core/args.h"
#include "common/core/expected.h"
#include "common/geometry/tet_generators.h"
#include "common/tissue/fem.h"

namespace vsurg::bench {

// The bar and its load, exactly as BM_FemStep builds them: 20 cm long, radius 2 cm, `rings`
// rings and 5·rings layers (4: 5 760 tetrahedra; 5: 11 250), the base fixed, `torque` N·m about
// the axis spread over the tip face (z = 0.2 m) as Saint-Venant's shear traction.
struct Bar {
  geometry::TetCylinder cylinder;
  std::vector<Eigen::Vector3d> tip_forces;  // on cylinder.tip, N
};
Expected<Bar> MakeBar(int rings, double torque = 2e-3);

// The files a peer reads (bench/peers/vegafem): the mesh and its material in VegaFEM's .veg text
// format (1-based), the fixed vertices and the tip forces (0-based), and the step's settings
// (dt and the Rayleigh damping).
Status ExportBar(const Bar& bar, const tissue::FemParams& p, double dt, const std::string& dir);

// The options both bar commands take, parsed and checked: --rings (1..12), --steps (1..100000),
// --tolerance in (0, 1). Returns the exit code when the command should end here (a refusal, 2;
// help, 0), else nothing.
struct BarRun {
  int rings = 0, steps = 0;
  double tolerance = 0;
};
std::optional<int> ParseBarRun(cli::ArgParser& p, const std::vector<std::string>& args,
                               BarRun& out);

int FemStep(const std::vector<std::string>& args);
// vsurg-bench hyper-step: one implicit-Euler step of the neo-Hookean FEM (hyper_step_command.cpp).
int HyperStep(const std::vector<std::string>& args);

}  // namespace vsurg::bench
