// The mass-spring benchmark scenes, shared by vsurg-microbench (bench/msm_bench.cpp) and
// vsurg-bench msm-step (which also writes them out for the peers: bench/peers/pbd).
//   0, 1: a sphere of 258 or 1026 particles (radius 5 cm), bottom fifth fixed, top pressed 5 mm;
//   2:    the default arm (6182 particles), elbow fixed, wrist ring turned by 60° (the coil
//         scene's twist at 2.07 N·m).
// Springs as BuildMassSpring's defaults (k 50 N/m structural, 5 N/m bending, c 0.05 N·s/m),
// mass 1050 kg/m³ of the enclosed volume. The drive is ramped in over 200 steps, then held.
#pragma once

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry/mesh_generators.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::bench {

inline constexpr double kMsmDt = 2e-4;  // s: 5 kHz, the rate a haptic-rate deformation needs

struct MsmScene {
  tissue::MassSpringModel model;
  std::vector<int> driven;  // kinematic particles, held at `target`
  std::vector<geometry::Vec3> target;
  std::vector<bool> fixed;
};

inline const char* MsmSceneName(int which) {
  return which == 0 ? "sphere258" : which == 1 ? "sphere1026" : "arm6182";
}

inline MsmScene MakeMsmScene(
    int which, tissue::Integrator integrator, double cg_tolerance = 1e-3,
    double cg_energy_floor = tissue::MassSpringStepParams{}.cg_energy_floor) {
  geometry::TriMesh mesh;
  if (which < 2) {
    mesh = *geometry::MakeSubdividedSphere(
        {0.05, which == 0 ? 3 : 4, geometry::SphereBase::kOctahedron});
  } else {
    mesh = geometry::MakeLimb(geometry::ForearmPreset())->surface;
  }
  tissue::MassSpringBuildParams bp;
  bp.total_mass = 1050.0 * geometry::SignedVolume(mesh);
  auto sys = tissue::BuildMassSpring(mesh, bp);
  tissue::MassSpringStepParams sp;
  sp.integrator = integrator;
  sp.cg_tolerance = cg_tolerance;
  sp.cg_energy_floor = cg_energy_floor;
  auto model = tissue::MassSpringModel::Create(*sys, sp);
  MsmScene s{std::move(*model), {}, {}, std::vector<bool>(mesh.positions.size(), false)};
  const double length = which == 2 ? geometry::ForearmPreset().length : 0;
  const Eigen::AngleAxisd twist(std::numbers::pi / 3, geometry::Vec3::UnitZ());
  for (int v = 0; v < mesh.VertexCount(); ++v) {
    const geometry::Vec3& p = mesh.positions[v];
    const bool fix = which < 2 ? p.z() < -0.03 : p.z() == 0.0;
    if (fix) s.model.SetFixed(v, true), s.fixed[v] = true;
    if (which < 2 ? p.z() > 0.0499 : p.z() == length) {
      s.driven.push_back(v);
      s.target.push_back(which < 2 ? geometry::Vec3(p - geometry::Vec3(0, 0, 0.005))
                                   : geometry::Vec3(twist * p));
    }
  }
  for (int v : s.driven) s.model.SetKinematic(v, true);
  for (int k = 1; k <= 200; ++k) {
    for (size_t d = 0; d < s.driven.size(); ++d) {
      const geometry::Vec3 rest = s.model.system().rest_positions[s.driven[d]];
      s.model.SetKinematicTarget(s.driven[d], rest + (s.target[d] - rest) * (k / 200.0));
    }
    s.model.Step(kMsmDt);
  }
  return s;
}

}  // namespace vsurg::bench
