// The press experiment of the mass-spring paper: a tool drives one vertex of a mass-spring tissue
// in by `press` metres over the first half of the run and holds it there, while the support is
// fixed (a sphere's bottom fifth resting on a table, a limb's two ends). Reports the final kinetic
// and potential energy (J), the largest displacement (m), the contact force the tool feels (N,
// along the outward direction), the step rate and whether the run diverged.
//
// `vsurg-sim msm` prints it; the study and the tests run it in-process.
#pragma once

#include <string>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::sim {

struct PressExperimentSpec {
  std::string mesh = "sphere";  // sphere, arm, calf or an OBJ file
  int particles = 1024;         // about this many surface particles (sphere, limbs)
  double radius = 0.05;         // sphere radius, m
  tissue::Integrator integrator = tissue::Integrator::kMidpoint;
  double dt = 0.001;  // s
  int steps = 1000;
  int substeps = 1;
  double press = 0.005;   // m
  double stiffness = 50;  // structural springs, N/m
  double bending = 5;     // bending springs, N/m (0: none)
  double damping = 0.05;  // N·s/m
  double density = 1050;  // kg/m³, for the total mass
  tissue::VolumeMode volume = tissue::VolumeMode::kNone;
};

struct PressExperimentResult {
  int particles = 0, springs = 0;
  int steps = 0;                                    // done (fewer than asked when the run diverged)
  double kinetic_energy = 0, potential_energy = 0;  // J
  double max_displacement = 0;                      // m
  double contact_force = 0;                         // N, the tissue's push along −direction
  geometry::Vec3 contact_force_vector = geometry::Vec3::Zero();
  double steps_per_second = 0;
  bool diverged = false;
  int cg_iterations_last = 0;  // implicit Euler only
};

// Errors name the spec's field ("mesh", "dt", "structural_stiffness", …).
Expected<PressExperimentResult> RunPressExperiment(const PressExperimentSpec& spec);

}  // namespace vsurg::sim
