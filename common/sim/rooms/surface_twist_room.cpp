#include "common/sim/rooms/surface_twist_room.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

Expected<SurfaceTwistRoom> SurfaceTwistRoom::Build(const RoomInputs& in) {
  auto fem = ReducedFemMesh(in.scene, in.rest);
  if (!fem.ok()) return fem.error();
  auto made =
      TableInputsFor<tissue::SurfaceTwistParams>(in.scene, in.rest, in.held, std::move(*fem));
  if (!made.ok()) return made.error();
  tissue::TableInputs<tissue::SurfaceTwistParams>& inputs = *made;
  inputs.params.jaw_radius = in.scene.region.reduced.jaw_radius;
  const tissue::ReducedCache cache(in.cache_dir);
  Status status = Status::Ok();
  SurfaceTwistRoom room;
  room.table_ = SharedSurfaceTwistTable(
      tissue::SurfaceTwistKey(inputs),
      [&] { return cache.SurfaceTwistFor(in.scene.name + "-surface-twist", inputs); }, status);
  if (!room.table_) return status.error();
  room.rest_ = &in.rest;
  room.max_twist_ = in.scene.region.reduced.max_twist;
  return room;
}

bool SurfaceTwistRoom::StartGrasp(const GraspQuery& q, GraspFrame& f) {
  const geometry::Triangle& tri = rest_->triangles[q.triangle];
  int k = 0;
  for (int j = 1; j < 3; ++j)
    if (q.barycentric[j] > q.barycentric[k]) k = j;
  f.grasp_vertex = tri[k];
  grasp_stiffness_ = tissue::SurfaceTwistStiffness(*table_, tri[k]);
  grasp_capacity_ = tissue::SurfaceTwistCapacity(*table_, tri[k], max_twist_);
  f.axis = q.normal;
  f.axis_point = q.point;
  f.lever = q.min_lever;
  return true;
}

TwistAnswer SurfaceTwistRoom::Twist(double twist) const {
  return LinearTwist(twist, grasp_stiffness_, grasp_capacity_);
}

std::optional<Deformed> SurfaceTwistRoom::Deform(const DeformInput& in) {
  if (!in.grasping) {
    if (!grasp_) return std::nullopt;
    grasp_.reset();
    return Deformed{&rest_->positions, false, false, std::nullopt};
  }
  if (!grasp_ || in.grasp_id != grasp_id_) {
    const tissue::TwistField field =
        tissue::SurfaceTwistField(*table_, in.grasp_vertex, rest_->positions, &fallback_);
    auto model = tissue::ReducedTwistModel::Create(field, rest_->positions, max_twist_);
    if (!model.ok()) return std::nullopt;
    grasp_ = std::make_unique<tissue::ReducedTwistModel>(std::move(*model));
    grasp_id_ = in.grasp_id;
    applied_torque_ = std::numeric_limits<double>::quiet_NaN();
  }
  if (in.torque == applied_torque_) return std::nullopt;  // nothing new
  const tissue::ReducedStats st = grasp_->Update(in.torque);
  applied_torque_ = in.torque;
  return Deformed{&grasp_->positions(), st.saturated, fallback_, std::nullopt};
}

}  // namespace vsurg::sim
