#include "common/sim/rooms/mass_spring_room.h"

#include "common/core/state_archive.h"

namespace vsurg::sim {

Expected<MassSpringRoom> MassSpringRoom::Build(const RoomInputs& in) {
  const RegionSpec& region = in.scene.region;
  tissue::MassSpringBuildParams bp = region.mass_spring;
  bp.total_mass = in.mass;
  auto sys = tissue::BuildMassSpring(in.rest, bp);
  if (!sys.ok()) return sys.error();
  tissue::MassSpringStepParams sp;
  sp.integrator = region.integrator;
  auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
  if (!model.ok()) return model.error();
  MassSpringRoom room;
  room.model_ = std::make_unique<tissue::MassSpringModel>(std::move(*model));
  const int n = in.rest.VertexCount();
  for (int v : in.held) {
    room.model_->SetFixed(v, true);
    if (bp.volume == tissue::VolumeMode::kInnerLayer) room.model_->SetFixed(n + v, true);
  }
  room.rest_ = &in.rest;
  room.dt_ = region.dt;
  room.coupling_k_ = in.proxy_stiffness;
  room.coupling_d_ = in.proxy_damping;
  return room;
}

std::optional<Deformed> MassSpringRoom::Deform(const DeformInput& in) {
  model_->ClearAnchors();
  if (in.triangle >= 0) {
    const auto& x = model_->positions();
    const geometry::Triangle& tri = rest_->triangles[in.triangle];
    const geometry::Vec3 scp = in.barycentric[0] * x[tri[0]] + in.barycentric[1] * x[tri[1]] +
                               in.barycentric[2] * x[tri[2]];
    const geometry::Vec3 offset = in.hip - scp;
    for (int k = 0; k < 3; ++k)
      model_->SetAnchor(tri[k], x[tri[k]] + offset, in.barycentric[k] * coupling_k_,
                        in.barycentric[k] * coupling_d_);
  }
  if (!model_->Step(dt_)) model_->Reset();  // a divergence is reset to rest, never NaN
  return Deformed{&model_->positions(), false, false, std::nullopt};
}

void MassSpringRoom::Save(StateWriter& w) const {
  w(model_->positions(), model_->velocities());
}

bool MassSpringRoom::Load(StateReader& r) {
  std::vector<geometry::Vec3> x(model_->positions().size()), v(model_->velocities().size());
  r(x, v);
  return r.ok() && model_->SetState(x, v).ok();
}

}  // namespace vsurg::sim
