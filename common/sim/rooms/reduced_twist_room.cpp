#include "common/sim/rooms/reduced_twist_room.h"

#include <algorithm>
#include <cmath>

#include "common/core/state_archive.h"
#include "common/geometry/distances.h"
#include "common/geometry/tet_generators.h"
#include "common/sim/rooms/room_support.h"
#include "common/tissue/reduced_cache.h"

namespace vsurg::sim {
namespace {

// The linear law: the FEM's twist field per unit torque (one static solve).
Expected<tissue::ReducedTwistModel> LinearModel(const RoomInputs& in,
                                                const geometry::TetCylinder& cylinder,
                                                const tissue::ReducedCache& cache) {
  tissue::TwistFieldInputs inputs;
  inputs.mesh = cylinder.mesh;
  inputs.material = SceneMaterial(in.scene);
  inputs.fixed = cylinder.base;
  inputs.face = cylinder.tip;
  inputs.face_area = cylinder.tip_area;
  inputs.origin = geometry::Vec3::Zero();
  inputs.axis = geometry::Vec3::UnitZ();
  inputs.display = in.rest.positions;
  auto field = cache.TwistFieldFor(in.scene.name + "-twist", inputs);
  if (!field.ok()) return field.error();
  return tissue::ReducedTwistModel::Create(*field, in.rest.positions,
                                           in.scene.region.reduced.max_twist);
}

// A hyperelastic law: the grasp turned to the table's levels up to max_twist on each side.
Expected<tissue::ReducedTwistModel> TableModel(const RoomInputs& in,
                                               const geometry::TetCylinder& cylinder,
                                               const tissue::ReducedCache& cache) {
  const Scene& scene = in.scene;
  tissue::TwistTableInputs inputs;
  inputs.mesh = cylinder.mesh;
  inputs.material.poisson = scene.poisson_ratio;
  inputs.material.young = 2 * scene.shear_modulus * (1 + scene.poisson_ratio);
  inputs.material.stiffening = scene.law == Scene::Law::kExponential ? scene.stiffening : 0.0;
  inputs.material.nodal_volume = scene.volume_at_vertices;
  inputs.fixed = cylinder.base;
  inputs.face = cylinder.tip;
  inputs.display = in.rest.positions;
  inputs.max_twist = scene.region.reduced.max_twist;
  inputs.levels = scene.region.reduced.levels;
  auto table = cache.TwistTableFor(scene.name + "-twist-table", inputs);
  if (!table.ok()) return table.error();
  return tissue::ReducedTwistModel::Create(*table, in.rest.positions,
                                           scene.region.reduced.max_twist);
}

}  // namespace

Expected<ReducedTwistRoom> ReducedTwistRoom::Build(const RoomInputs& in) {
  // The FEM: the limb's tapered cylinder (its proximal end fixed at z = 0, the torque on the
  // distal face), meshed for torsion.
  if (in.centreline.size() < 2)
    return InvalidArgument("regions[0].model.mode", "a reduced twist model needs a limb mesh");
  const geometry::LimbParams& limb = in.scene.mesh.limb;
  auto cylinder = geometry::MakeTetCylinder(geometry::TorsionCylinder(
      limb.length, limb.radius_proximal, limb.radius_distal, in.scene.region.reduced.fem_rings));
  if (!cylinder.ok()) return cylinder.error();
  const tissue::ReducedCache cache(in.cache_dir);
  auto model = in.scene.law == Scene::Law::kLinear ? LinearModel(in, *cylinder, cache)
                                                   : TableModel(in, *cylinder, cache);
  if (!model.ok()) return model.error();
  ReducedTwistRoom room;
  room.model_ = std::make_unique<tissue::ReducedTwistModel>(std::move(*model));
  room.centreline_ = &in.centreline;
  if (!in.scene.relaxation.empty()) {
    auto relax = tissue::TorqueRelaxation::Create(in.scene.relaxation);
    if (!relax.ok()) return Error{relax.error().code, relax.error().message, "tissue.relaxation"};
    room.relax_ = std::move(*relax);
  }
  return room;
}

bool ReducedTwistRoom::StartGrasp(const GraspQuery& q, GraspFrame& f) const {
  f = LimbGraspFrame(*centreline_, q);
  return true;
}

TwistAnswer ReducedTwistRoom::Twist(double twist) const {
  const tissue::ReducedTwistModel::Answer a = model_->TorqueAt(twist);
  if (!relax_) return {a.torque, a.stiffness, a.overload};
  return {relax_->Torque(a.torque, step_), step_.scale * a.stiffness, a.overload, a.torque};
}

void ReducedTwistRoom::BeginTwistStep(double dt, double now) {
  if (!relax_) return;
  if (const double gap = now - dt - last_end_; gap > 0) relax_->Hold(gap);
  step_dt_ = dt;
  step_end_ = now;
  step_ = relax_->Over(dt);
}

void ReducedTwistRoom::EndTwistStep(double twist) {
  if (!relax_) return;
  relax_->Commit(model_->TorqueAt(twist).torque, step_);
  last_end_ = step_end_;
}

void ReducedTwistRoom::ReleaseTwist(double dt, double now) {
  if (!relax_) return;
  BeginTwistStep(dt, now);
  relax_->Commit(0.0, step_);
  last_end_ = now;
}

void ReducedTwistRoom::Save(StateWriter& w) const {
  w(relax_.has_value(), step_dt_, step_end_, last_end_);
  if (relax_) w(*relax_);
}

bool ReducedTwistRoom::Load(StateReader& r) {
  bool relaxes = false;
  r(relaxes, step_dt_, step_end_, last_end_);
  if (!r.ok() || relaxes != relax_.has_value()) return false;
  if (relax_) {
    r(*relax_);
    step_ = relax_->Over(step_dt_);
  }
  return r.ok();
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
