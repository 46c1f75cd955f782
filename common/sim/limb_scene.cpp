#include "common/sim/limb_scene.h"

#include <cmath>
#include <numbers>

namespace vsurg::sim {
namespace {

LimbScene Arm() {
  LimbScene s;
  s.name = "arm";
  s.limb = geometry::ForearmPreset();  // 25 cm, radius 4 → 3 cm, 6182 vertices
  tissue::CoilSpringParams& c = s.coil;
  c.core_radius = 0.02;  // the grip covers 2 cm of the wrist
  c.thickness = 0.01;
  c.coils = 23;    // r + S·h = 0.25 m: the last coil reaches the elbow
  c.width = 0.06;  // about the limb's diameter
  // Capacity Σ C_i = 2π·F_t·Σ R_i = 3.30 N·m, the largest forearm rotation torque.
  c.max_force = 3.30 / (2.0 * std::numbers::pi *
                        (c.coils * c.core_radius + c.thickness * c.coils * (c.coils + 1) / 2.0));
  c.friction = 1.25;
  // Effective modulus: the coil-spring paper's 2.07 N·m turns the wrist by 60° (1.047 rad), inside
  // the passive pronation–supination range. Checked by
  // LimbSceneTest.ArmTwistsSixtyDegreesAtPaperTorque.
  c.modulus = 4.2530e8;
  s.reference =
      tissue::TaperedShaft{s.limb.length, s.limb.radius_proximal, s.limb.radius_distal, 12e3};
  return s;
}

LimbScene Calf() {
  LimbScene s;
  s.name = "calf";
  s.limb = geometry::CalfPreset();  // 36 cm, radius 5.5 → 3.5 cm
  tissue::CoilSpringParams& c = s.coil;
  c.core_radius = 0.02;
  c.thickness = 0.01;
  c.coils = 34;  // r + S·h = 0.36 m
  c.width = 0.09;
  // Capacity 6 N·m: the lower leg is about twice as strong in rotation as the forearm.
  c.max_force = 6.0 / (2.0 * std::numbers::pi *
                       (c.coils * c.core_radius + c.thickness * c.coils * (c.coils + 1) / 2.0));
  c.friction = 1.25;
  // 2.07 N·m turns the ankle end by 30° (0.524 rad). Checked by LimbSceneTest.
  c.modulus = 6.0131e8;
  s.reference =
      tissue::TaperedShaft{s.limb.length, s.limb.radius_proximal, s.limb.radius_distal, 12e3};
  return s;
}

}  // namespace

Expected<LimbScene> BuiltinLimbScene(std::string_view name) {
  if (name == "arm") return Arm();
  if (name == "calf") return Calf();
  return Error{ErrorCode::kNotFound,
               "unknown scene '" + std::string(name) + "' (built in: arm, calf)", "scene"};
}

Expected<LimbSceneInstance> Instantiate(const LimbScene& scene) {
  auto limb = geometry::MakeLimb(scene.limb);
  if (!limb.ok()) return limb.error();
  auto model = tissue::CoilSpringModel::Create(scene.coil);
  if (!model.ok()) return model.error();
  // The grasp holds the distal end (wrist, ankle); the proximal end is the fixed one.
  const double grasp = geometry::ArcLengths(limb->centreline).back();
  auto deformer =
      tissue::CoilDeformer::CreateForLimb(*model, limb->surface.positions, limb->centreline, grasp);
  if (!deformer.ok()) return deformer.error();
  return LimbSceneInstance{scene, std::move(*limb), std::move(*model), std::move(*deformer)};
}

}  // namespace vsurg::sim
