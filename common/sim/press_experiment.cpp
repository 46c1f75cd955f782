#include "common/sim/press_experiment.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/geometry/mesh_generators.h"
#include "common/sim/scene.h"

namespace vsurg::sim {
namespace {

// A mesh to press: the subdivided sphere, a limb, or an OBJ file. `press` is the vertex the tool
// drives, `direction` the way it pushes, `fixed` the support.
struct PressScene {
  geometry::TriMesh mesh;
  int press = 0;
  geometry::Vec3 direction = geometry::Vec3(0, 0, -1);
  std::vector<int> fixed;
};

Expected<PressScene> MakePressScene(const std::string& name, int particles, double radius) {
  PressScene s;
  const bool limb = name == "arm" || name == "calf";
  sim::MeshSpec spec;
  if (name == "sphere") {
    spec.kind = sim::MeshKind::kSphere;
    spec.radius = radius;
    spec.particles = particles;
  } else if (limb) {
    spec.kind = sim::MeshKind::kLimb;
    spec.limb = geometry::WithResolution(
        name == "arm" ? geometry::ForearmPreset() : geometry::CalfPreset(), particles);
  } else {
    spec.kind = sim::MeshKind::kFile;
    spec.path = name;
  }
  auto mesh = sim::BuildSceneMesh(spec);
  if (!mesh.ok()) return mesh.error();
  s.mesh = std::move(mesh->surface);
  // Limbs lie along z: press the top (+y) of the middle and hold both ends. Anything else:
  // press the top (+z) and rest the bottom fifth on a table.
  s.fixed = sim::SupportedVertices(s.mesh, limb ? sim::Support::kEnds : sim::Support::kBottom);
  Eigen::Vector3d lo = s.mesh.positions[0], hi = lo;
  for (const auto& p : s.mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double mid_z = 0.5 * (lo.z() + hi.z());
  double best = -1e300;
  for (int v = 0; v < s.mesh.VertexCount(); ++v) {
    const auto& p = s.mesh.positions[v];
    const double score = limb ? p.y() - 10 * std::abs(p.z() - mid_z) : p.z();
    if (score > best) best = score, s.press = v;
  }
  if (limb) s.direction = geometry::Vec3(0, -1, 0);
  return s;
}

}  // namespace

Expected<PressExperimentResult> RunPressExperiment(const PressExperimentSpec& spec) {
  if (!(spec.dt > 0 && spec.dt <= 1)) return InvalidArgument("dt", "must be in (0, 1] s");
  if (spec.steps < 1 || spec.steps > 10'000'000)
    return InvalidArgument("steps", "must be in 1..10000000");
  if (spec.substeps < 1 || spec.substeps > 1000)
    return InvalidArgument("substeps", "must be in 1..1000");
  if (spec.particles < 6 || spec.particles > 300000)
    return InvalidArgument("particles", "must be in 6..300000");
  if (!(spec.radius > 0)) return InvalidArgument("radius", "must be > 0 m");
  if (!(std::abs(spec.press) < 0.1)) return InvalidArgument("press", "must be within ±0.1 m");
  if (!(spec.density > 0)) return InvalidArgument("density", "must be > 0");
  auto scene = MakePressScene(spec.mesh, spec.particles, spec.radius);
  if (!scene.ok()) {
    Error e = scene.error();
    e.field = "mesh";
    return e;
  }
  tissue::MassSpringBuildParams bp;
  bp.total_mass = spec.density * std::abs(geometry::SignedVolume(scene->mesh));
  bp.structural_stiffness = spec.stiffness;
  bp.bending_stiffness = spec.bending;
  bp.volume_stiffness = bp.structural_stiffness;
  bp.damping = spec.damping;
  bp.volume = spec.volume;
  bp.layer_depth = 0.2 * spec.radius;
  auto system = tissue::BuildMassSpring(scene->mesh, bp);
  if (!system.ok()) return system.error();
  PressExperimentResult r;
  r.particles = static_cast<int>(system->rest_positions.size());
  r.springs = static_cast<int>(system->springs.size());
  tissue::MassSpringStepParams sp;
  sp.integrator = spec.integrator;
  auto model = tissue::MassSpringModel::Create(std::move(*system), sp);
  if (!model.ok()) return model.error();
  for (int v : scene->fixed) model->SetFixed(v, true);
  if (bp.volume == tissue::VolumeMode::kInnerLayer) {
    const int n = scene->mesh.VertexCount();
    for (int v : scene->fixed) model->SetFixed(n + v, true);
  }
  model->SetKinematic(scene->press, true);
  const geometry::Vec3 rest = scene->mesh.positions[scene->press];
  const int ramp = std::max(1, spec.steps / 2);
  const auto t0 = std::chrono::steady_clock::now();
  for (; r.steps < spec.steps; ++r.steps) {
    const double depth = spec.press * std::min(1.0, static_cast<double>(r.steps + 1) / ramp);
    model->SetKinematicTarget(scene->press, rest + depth * scene->direction);
    if (!model->Step(spec.dt, spec.substeps)) break;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The tissue's push on the tool, as a force along the outward direction (−press direction).
  r.contact_force_vector = model->InternalForceOn(scene->press);
  r.contact_force = r.contact_force_vector.dot(-scene->direction);
  r.steps_per_second = seconds > 0 ? r.steps / seconds : 0.0;
  r.kinetic_energy = model->KineticEnergy();
  r.potential_energy = model->PotentialEnergy();
  r.max_displacement = model->MaxDisplacement();
  r.diverged = model->diverged();
  if (spec.integrator == tissue::Integrator::kImplicitEuler)
    r.cg_iterations_last = model->last_cg_iterations();
  return r;
}

}  // namespace vsurg::sim
