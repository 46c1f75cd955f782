// The mass-spring model's room (the mass-spring paper; common/sim/tissue_room.h has the contract):
// palpation. The proxy's force enters the solve as zero-length spring-dampers from the contact
// triangle's vertices towards the tip (barycentric shares of the coupling's K and D), inside the
// implicit step: a coupling stiffer than the tissue applied as an explicit force made the
// 1026-particle sphere chatter at the device's rate limit. A step that diverges resets the tissue
// to rest.
#pragma once

#include <memory>
#include <optional>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::sim {

class MassSpringRoom {
 public:
  static constexpr bool kPaced = true;  // steps at the scene's dt
  static Expected<MassSpringRoom> Build(const RoomInputs& in);
  // Deformation thread: one step of region.dt with the contact's anchors.
  std::optional<Deformed> Deform(const DeformInput& in);
  // Its state (live migration): every particle's position and velocity.
  void Save(StateWriter& w) const;
  bool Load(StateReader& r);

 private:
  // Deformation thread only.
  std::unique_ptr<tissue::MassSpringModel> model_;
  const geometry::TriMesh* rest_ = nullptr;
  double dt_ = 1e-3;                        // s
  double coupling_k_ = 0, coupling_d_ = 0;  // N/m, N·s/m: the proxy's
};

}  // namespace vsurg::sim
