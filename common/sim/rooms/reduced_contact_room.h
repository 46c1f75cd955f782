// The reduced contact model's room (Green's functions of the FEM, Cotin et al. 1999; the contact
// table with its rotation correction, common/tissue/reduced.h; common/sim/tissue_room.h has the
// contract). Quasi-static: the surface is the table's answer to the tool pressing at the contact
// point, the proxy's spring and the tissue solved together (stable whatever the spring's
// stiffness). The station's local model is the proxy's spring in series with the tissue behind
// it, k/(1 + k·nᵀGn).
#pragma once

#include <memory>
#include <optional>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/reduced.h"

namespace vsurg::sim {

class ReducedContactRoom {
 public:
  static constexpr bool kPaced = false;
  static Expected<ReducedContactRoom> Build(const RoomInputs& in);
  // Haptic thread: the local model's stiffness at a contact (reads the immutable table only).
  double ContactStiffness(const ContactQuery& q) const;
  // Deformation thread.
  std::optional<Deformed> Deform(const DeformInput& in);

 private:
  // The model's table is immutable and shared (both threads read it); its positions are the
  // deformation thread's.
  std::unique_ptr<tissue::ReducedContactModel> model_;
  const geometry::TriMesh* rest_ = nullptr;
  double coupling_k_ = 0;  // N/m, the proxy's
  // Deformation thread: the last contact applied (-2: none yet).
  int seen_triangle_ = -2;
  geometry::Vec3 applied_hip_ = geometry::Vec3::Zero();
  geometry::Vec3 applied_barycentric_ = geometry::Vec3::Zero();
};

}  // namespace vsurg::sim
