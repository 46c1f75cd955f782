#include "common/sim/rooms/reduced_contact_room.h"

#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

Expected<ReducedContactRoom> ReducedContactRoom::Build(const RoomInputs& in) {
  const RegionSpec& region = in.scene.region;
  auto fem = ReducedFemMesh(in.scene, in.rest);
  if (!fem.ok()) return fem.error();
  auto made =
      TableInputsFor<tissue::ContactResponseParams>(in.scene, in.rest, in.held, std::move(*fem));
  if (!made.ok()) return made.error();
  tissue::TableInputs<tissue::ContactResponseParams>& inputs = *made;
  inputs.params.footprint_radius = region.reduced.footprint_radius;
  inputs.params.rotation = region.reduced.rotation;
  Status status = Status::Ok();
  const tissue::ReducedCache cache(in.cache_dir);
  auto table = SharedContactTable(
      tissue::ContactKey(inputs),
      [&] { return cache.ContactResponseFor(in.scene.name + "-contact", inputs); }, status);
  if (!table) return status.error();
  auto model =
      tissue::ReducedContactModel::Create(table, in.rest.positions, region.reduced.max_force);
  if (!model.ok()) return model.error();
  ReducedContactRoom room;
  room.model_ = std::make_unique<tissue::ReducedContactModel>(std::move(*model));
  room.rest_ = &in.rest;
  room.coupling_k_ = in.proxy_stiffness;
  return room;
}

double ReducedContactRoom::ContactStiffness(const ContactQuery& q) const {
  const geometry::Triangle& t = q.triangle;
  return model_->SeriesStiffness({t[0], t[1], t[2]},
                                 {q.barycentric[0], q.barycentric[1], q.barycentric[2]},
                                 q.rest_normal, q.proxy_stiffness);
}

std::optional<Deformed> ReducedContactRoom::Deform(const DeformInput& in) {
  if (in.triangle == seen_triangle_ && in.hip == applied_hip_ &&
      in.barycentric == applied_barycentric_)
    return std::nullopt;  // nothing new
  seen_triangle_ = in.triangle;
  applied_hip_ = in.hip;
  applied_barycentric_ = in.barycentric;
  bool overload = false, outside_model = false;
  if (in.triangle >= 0) {
    // The force spread over the contact triangle by the contact point's barycentric coordinates.
    const geometry::Triangle& tri = rest_->triangles[in.triangle];
    const geometry::Vec3 p0 = RestPoint(*rest_, in.triangle, in.barycentric);
    const tissue::ReducedStats st = model_->PressWithSpring(
        {tri[0], tri[1], tri[2]}, {in.barycentric[0], in.barycentric[1], in.barycentric[2]}, in.hip,
        p0, geometry::TriangleNormal(*rest_, in.triangle), coupling_k_);
    if (!st.ok) model_->Release();
    overload = st.saturated;
    outside_model = st.fallback;
  } else {
    model_->Release();
  }
  return Deformed{&model_->positions(), overload, outside_model, std::nullopt};
}

}  // namespace vsurg::sim
