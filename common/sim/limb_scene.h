// Built-in limb-torsion scenes (the coil-spring paper §3: arm and calf twisted by a torque), the
// embedded defaults that `vsurg-sim deform` and the demo run.
//
// The coil parameters are phenomenological (DESIGN.md "Model 1"): the coils tile the limb from
// the grasp at the distal end to the fixed proximal end (r + S·h = limb length), the capacity
// Σ C_i is the largest torque the limb tolerates (overload past it is a safety event), and E
// is an effective modulus of the coil section, not the tissue's Young's modulus, chosen so a
// reference torque gives a physiological twist. The Saint-Venant shaft (G, ν) is the analytic
// reference the calibration fits against.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh_generators.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/torsion_reference.h"

namespace vsurg::sim {

struct LimbScene {
  std::string name;
  geometry::LimbParams limb;
  tissue::CoilSpringParams coil;
  tissue::TaperedShaft reference;  // Saint-Venant shaft of the same limb, soft tissue only
  double poisson_ratio = 0.47;
  double density = 1050;         // kg/m³
  double default_torque = 2.07;  // N·m, the coil-spring paper §3
};

// "arm" (forearm) or "calf"; kNotFound otherwise.
Expected<LimbScene> BuiltinLimbScene(std::string_view name);

// A scene made concrete: its mesh, its model and a deformer bound to the mesh (grasp at the
// distal end, limb mode).
struct LimbSceneInstance {
  LimbScene scene;
  geometry::Limb limb;
  tissue::CoilSpringModel model;
  tissue::CoilDeformer deformer;
};
Expected<LimbSceneInstance> Instantiate(const LimbScene& scene);

}  // namespace vsurg::sim
