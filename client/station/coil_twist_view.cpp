#include "client/station/coil_twist_view.h"

#include <cmath>
#include <numeric>

#include "common/sim/rooms/room_types.h"

namespace vsurg::client {

std::optional<CoilTwistView> CoilTwistView::For(const sim::Scene& scene,
                                                const sim::SceneMesh& mesh) {
  const uint64_t key = sim::CoilLimbKeyOf(scene, mesh);
  if (key == 0) return std::nullopt;
  auto model = tissue::CoilSpringModel::Create(scene.region.coil);
  if (!model.ok()) return std::nullopt;
  CoilTwistView v;
  v.model_ = std::make_shared<const tissue::CoilSpringModel>(std::move(*model));
  auto projection = geometry::ProjectOntoPolyline(mesh.surface.positions, mesh.centreline);
  if (!projection.ok()) return std::nullopt;
  v.rest_ = mesh.surface.positions;
  v.projection_ = std::move(*projection);
  v.length_ = geometry::ArcLengths(mesh.centreline).back();
  v.key_ = key;
  return v;
}

bool CoilTwistView::Shape(const wire::CoilTwist& twist, std::vector<int32_t>& indices,
                          std::vector<geometry::Vec3>& positions) {
  if (twist.key != key_ || !std::isfinite(twist.arc) || !std::isfinite(twist.torque) ||
      twist.arc < 0 || twist.arc > length_)
    return false;
  if (!deformer_ || twist.grasp != grasp_ || twist.arc != arc_) {
    auto d = tissue::CoilDeformer::CreateForLimb(*model_, rest_, projection_, length_, twist.arc);
    if (!d.ok()) return false;
    deformer_ = std::make_unique<tissue::CoilDeformer>(std::move(*d));
    grasp_ = twist.grasp;
    arc_ = twist.arc;
  }
  deformer_->Update(twist.torque);
  const std::vector<geometry::Vec3>& p = deformer_->positions();
  indices.resize(p.size());
  std::iota(indices.begin(), indices.end(), 0);
  positions.assign(p.begin(), p.end());
  return true;
}

}  // namespace vsurg::client
