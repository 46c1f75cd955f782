// The ring-layer reduced model's room (the mass-spring paper §3.3; common/sim/tissue_room.h has the
// contract): at each new contact, rings around the contact point that move together, joined by
// equal springs; the contact force's normal part drives them.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/ring_layer.h"

namespace vsurg::sim {

class RingLayerRoom {
 public:
  static constexpr bool kPaced = true;  // steps at the scene's dt
  static Expected<RingLayerRoom> Build(const RoomInputs& in);
  // Deformation thread. A new contact builds its rings (allocates: once per contact).
  std::optional<Deformed> Deform(const DeformInput& in);
  // Its state (live migration): the contact's rings and their motion.
  void Save(StateWriter& w) const;
  bool Load(StateReader& r);

 private:
  // Deformation thread only.
  const geometry::TriMesh* rest_ = nullptr;
  tissue::RingLayerParams params_;
  double dt_ = 1e-3;            // s
  std::vector<double> masses_;  // kg, per surface vertex
  std::unique_ptr<tissue::RingLayerModel> ring_;
  uint64_t seen_contact_ = 0;
  int ring_triangle_ = -1;  // where the rings were built
  geometry::Vec3 ring_barycentric_ = geometry::Vec3::Zero();
  void BuildRings(int triangle, const geometry::Vec3& barycentric);
};

}  // namespace vsurg::sim
