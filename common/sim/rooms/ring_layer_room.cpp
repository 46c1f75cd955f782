#include "common/sim/rooms/ring_layer_room.h"

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
    const geometry::Vec3 p = RestPoint(rest, in.triangle, in.barycentric);
    std::vector<double> rho(rest.VertexCount());
    for (int v = 0; v < rest.VertexCount(); ++v) rho[v] = (rest.positions[v] - p).norm();
    auto ring = tissue::RingLayerModel::Create(
        rest.positions, rho, masses_, -geometry::TriangleNormal(rest, in.triangle), params_);
    if (ring.ok()) ring_ = std::make_unique<tissue::RingLayerModel>(std::move(*ring));
  }
  if (!ring_) return std::nullopt;
  ring_->SetContactForce(in.triangle >= 0
                             ? in.force_on_tissue.dot(-geometry::TriangleNormal(rest, in.triangle))
                             : 0.0);
  ring_->Step(dt_);
  ring_->Apply();
  return Deformed{&ring_->positions(), false, false};
}

}  // namespace vsurg::sim
