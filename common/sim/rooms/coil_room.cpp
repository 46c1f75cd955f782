#include "common/sim/rooms/coil_room.h"

#include <algorithm>
#include <cmath>

#include "common/geometry/distances.h"
#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

namespace {

struct Fnv1a {
  uint64_t h = 1469598103934665603ull;
  void Bytes(const void* p, size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  }
  template <class T>
  void Value(const T& v) {
    Bytes(&v, sizeof v);
  }
  void Points(const std::vector<geometry::Vec3>& points) {
    Value(points.size());
    for (const geometry::Vec3& p : points) Value(p.x()), Value(p.y()), Value(p.z());
  }
};

}  // namespace

uint64_t CoilLimbKey(const tissue::CoilSpringParams& model, const std::vector<geometry::Vec3>& rest,
                     const std::vector<geometry::Vec3>& centreline) {
  Fnv1a f;
  f.Value(model.core_radius), f.Value(model.thickness), f.Value(model.width);
  f.Value(model.coils), f.Value(model.modulus), f.Value(model.max_force);
  f.Value(model.friction);
  f.Value(model.coil_rigidity.size());
  for (double r : model.coil_rigidity) f.Value(r);
  f.Points(rest);
  f.Points(centreline);
  return f.h == 0 ? 1 : f.h;  // 0 means "none" on the wire
}

uint64_t CoilLimbKeyOf(const Scene& scene, const SceneMesh& mesh) {
  const RegionSpec& region = scene.region;
  if (region.kind != ModelKind::kCoil || region.coil_mode != tissue::TwistMode::kLimb ||
      mesh.centreline.size() < 2)
    return 0;
  return CoilLimbKey(region.coil, mesh.surface.positions, mesh.centreline);
}

Expected<CoilRoom> CoilRoom::Build(const RoomInputs& in) {
  const RegionSpec& region = in.scene.region;
  auto coil = tissue::CoilSpringModel::Create(region.coil);
  if (!coil.ok()) return coil.error();
  if (region.coil_mode == tissue::TwistMode::kLimb && in.centreline.size() < 2)
    return InvalidArgument("regions[0].model.mode",
                           "limb mode needs a limb mesh (with a centreline)");
  CoilRoom room;
  room.coil_ = std::make_shared<const tissue::CoilSpringModel>(std::move(*coil));
  room.mode_ = region.coil_mode;
  room.rest_ = &in.rest;
  room.centreline_ = &in.centreline;
  if (room.mode_ == tissue::TwistMode::kLimb) {
    room.key_ = CoilLimbKey(region.coil, in.rest.positions, in.centreline);
    auto projection = geometry::ProjectOntoPolyline(in.rest.positions, in.centreline);
    if (!projection.ok()) return projection.error();
    room.projection_ =
        std::make_shared<const std::vector<geometry::CentrelineProjection>>(std::move(*projection));
    room.length_ = geometry::ArcLengths(in.centreline).back();
  }
  return room;
}

bool CoilRoom::StartGrasp(const GraspQuery& q, GraspFrame& f) const {
  if (mode_ == tissue::TwistMode::kLimb) {
    f = LimbGraspFrame(*centreline_, q);
  } else {
    f.axis = q.normal;
    f.axis_point = q.point;
    f.lever = q.min_lever;
  }
  return true;
}

TwistAnswer CoilRoom::Twist(double twist) const {
  const tissue::CoilTorque a = coil_->Inverse(twist);
  return {a.torque, a.stiffness, a.overload};
}

std::optional<Deformed> CoilRoom::Deform(const DeformInput& in) {
  if (in.grasping && in.grasp_id != seen_grasp_) {
    // A new grasp: bind a deformer around it (set-up work, on this thread).
    seen_grasp_ = in.grasp_id;
    Expected<tissue::CoilDeformer> d = InvalidArgument("grasp", "no grasp");
    double arc = 0;
    if (mode_ == tissue::TwistMode::kLimb) {
      arc = geometry::ProjectPointOntoPolyline(*centreline_, in.grasp_point).s;
      d = tissue::CoilDeformer::CreateForLimb(*coil_, rest_->positions, *projection_, length_, arc);
    } else {
      auto sp = geometry::ClosestSurfacePoint(*rest_, in.grasp_point);
      if (sp.ok())
        d = tissue::CoilDeformer::CreateForSurface(*coil_, *rest_, *sp,
                                                   geometry::GeodesicMethod::kHeat);
    }
    if (d.ok()) {
      if (deformer_) deformer_->Update(0.0);
      deformer_ = std::make_unique<tissue::CoilDeformer>(std::move(*d));
      bound_ = {in.grasp_id, arc};
      applied_torque_ = NAN;
    }
  }
  if (!deformer_) return std::nullopt;
  const double torque = in.grasping ? in.torque : 0.0;
  if (torque == applied_torque_ && in.grasping == applied_grasp_) return std::nullopt;
  // While the hand grasps, the haptic path answers from the model's inverse and the view is the
  // only reader of the vertices, at its own frame rate or not at all (a station that remakes the
  // twist itself): the update evaluates the model and leaves the turning to the view. The release
  // turns them here, for the surface the haptic path answers from next.
  const tissue::DeformStats stats =
      in.grasping ? deformer_->Evaluate(torque) : deformer_->Update(torque);
  applied_torque_ = torque;
  applied_grasp_ = in.grasping;
  Deformed d;
  d.positions = in.grasping ? nullptr : &deformer_->positions();
  d.overload = stats.overload;
  if (in.grasping) d.turn = deformer_->table(), d.turn_state = &deformer_->state();
  if (mode_ == tissue::TwistMode::kLimb)
    d.twist = CoilTwistShape{key_, bound_.first, bound_.second, torque};
  return d;
}

}  // namespace vsurg::sim
