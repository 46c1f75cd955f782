#include "common/sim/rooms/ring_layer_room.h"

#include "common/core/state_archive.h"
#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

Expected<RingLayerRoom> RingLayerRoom::Build(const RoomInputs& in) {
  RingLayerRoom room;
  room.rest_ = &in.rest;
  room.params_ = in.scene.region.ring;
  room.dt_ = in.scene.region.dt;
  room.masses_.assign(in.rest.VertexCount(), in.mass / in.rest.VertexCount());
  return room;
}

std::optional<Deformed> RingLayerRoom::Deform(const DeformInput& in) {
  const geometry::TriMesh& rest = *rest_;
  if (in.triangle >= 0 && in.contact_id != seen_contact_) {
    seen_contact_ = in.contact_id;
    BuildRings(in.triangle, in.barycentric);
  }
  if (!ring_) return std::nullopt;
  ring_->SetContactForce(in.triangle >= 0
                             ? in.force_on_tissue.dot(-geometry::TriangleNormal(rest, in.triangle))
                             : 0.0);
  ring_->Step(dt_);
  ring_->Apply();
  return Deformed{&ring_->positions(), false, false, std::nullopt};
}

void RingLayerRoom::BuildRings(int triangle, const geometry::Vec3& barycentric) {
  const geometry::TriMesh& rest = *rest_;
  const geometry::Vec3 p = RestPoint(rest, triangle, barycentric);
  std::vector<double> rho(rest.VertexCount());
  for (int v = 0; v < rest.VertexCount(); ++v) rho[v] = (rest.positions[v] - p).norm();
  auto ring = tissue::RingLayerModel::Create(rest.positions, rho, masses_,
                                             -geometry::TriangleNormal(rest, triangle), params_);
  if (!ring.ok()) return;
  ring_ = std::make_unique<tissue::RingLayerModel>(std::move(*ring));
  ring_triangle_ = triangle;
  ring_barycentric_ = barycentric;
}

void RingLayerRoom::Save(StateWriter& w) const {
  w(seen_contact_, ring_ != nullptr);
  if (ring_) {
    w(ring_triangle_, ring_barycentric_);
    w(*ring_);
  }
}

bool RingLayerRoom::Load(StateReader& r) {
  bool has_rings = false;
  r(seen_contact_, has_rings);
  ring_.reset();
  if (!r.ok() || !has_rings) return r.ok();
  int triangle = -1;
  geometry::Vec3 barycentric;
  r(triangle, barycentric);
  if (!r.ok() || triangle < 0 || triangle >= rest_->TriangleCount()) return false;
  BuildRings(triangle, barycentric);
  if (!ring_) return false;
  r(*ring_);
  return r.ok();
}

}  // namespace vsurg::sim
