#include "common/sim/rooms/reduced_twist_room.h"

#include <algorithm>
#include <cmath>

#include "common/geometry/distances.h"
#include "common/geometry/tet_generators.h"
#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

Expected<ReducedTwistRoom> ReducedTwistRoom::Build(const RoomInputs& in) {
  // The FEM: the limb's tapered cylinder (its proximal end fixed at z = 0, the torque on the
  // distal face), meshed for torsion.
  if (in.centreline.size() < 2)
    return InvalidArgument("regions[0].model.mode", "a reduced twist model needs a limb mesh");
  const geometry::LimbParams& limb = in.scene.mesh.limb;
  auto cylinder = geometry::MakeTetCylinder(geometry::TorsionCylinder(
      limb.length, limb.radius_proximal, limb.radius_distal, in.scene.region.reduced.fem_rings));
  if (!cylinder.ok()) return cylinder.error();
  tissue::TwistFieldInputs inputs;
  inputs.mesh = cylinder->mesh;
  inputs.material = SceneMaterial(in.scene);
  inputs.fixed = cylinder->base;
  inputs.face = cylinder->tip;
  inputs.face_area = cylinder->tip_area;
  inputs.origin = geometry::Vec3::Zero();
  inputs.axis = geometry::Vec3::UnitZ();
  inputs.display = in.rest.positions;
  const tissue::ReducedCache cache(in.cache_dir);
  auto field = cache.TwistFieldFor(in.scene.name + "-twist", inputs);
  if (!field.ok()) return field.error();
  auto model = tissue::ReducedTwistModel::Create(*field, in.rest.positions,
                                                 in.scene.region.reduced.max_twist);
  if (!model.ok()) return model.error();
  ReducedTwistRoom room;
  room.model_ = std::make_unique<tissue::ReducedTwistModel>(std::move(*model));
  room.centreline_ = &in.centreline;
  return room;
}

bool ReducedTwistRoom::StartGrasp(const GraspQuery& q, GraspFrame& f) const {
  f = LimbGraspFrame(*centreline_, q);
  return true;
}

TwistAnswer ReducedTwistRoom::Twist(double twist) const {
  return LinearTwist(twist, model_->grasp_stiffness(), model_->torque_capacity());
}

std::optional<Deformed> ReducedTwistRoom::Deform(const DeformInput& in) {
  const double torque = in.grasping ? in.torque : 0.0;
  if (torque == applied_torque_ && in.grasping == applied_grasp_) return std::nullopt;
  const tissue::ReducedStats st = model_->Update(torque);
  applied_torque_ = torque;
  applied_grasp_ = in.grasping;
  return Deformed{&model_->positions(), st.saturated, false, std::nullopt};
}

}  // namespace vsurg::sim
