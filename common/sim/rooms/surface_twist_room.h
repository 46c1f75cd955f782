// The surface twist model's room (forceps on an organ: one FEM twist field per vertex the jaws
// may hold, common/tissue/reduced.h 4.; common/sim/tissue_room.h has the contract). A grasp holds
// the contact triangle's nearest vertex; the haptic thread answers its twist linearly with that
// vertex's stiffness, up to its capacity (table reads: no allocation); the deformation thread
// builds the grasp's twist model when it starts and turns the organ about the normal at the jaws.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/reduced.h"

namespace vsurg::sim {

class SurfaceTwistRoom {
 public:
  static constexpr bool kPaced = false;
  static Expected<SurfaceTwistRoom> Build(const RoomInputs& in);
  // Haptic thread: the jaws' vertex, its stiffness and capacity; the axis is the normal there.
  bool StartGrasp(const GraspQuery& q, GraspFrame& f);
  TwistAnswer Twist(double twist) const;
  // Haptic thread: only a grasp deforms this model (SameGraspRequest).
  static bool SameRequest(const DeformInput& a, const DeformInput& b) {
    return SameGraspRequest(a, b);
  }
  // Deformation thread. A new grasp builds its twist model (allocates: once per grasp);
  // released: at rest.
  std::optional<Deformed> Deform(const DeformInput& in);

 private:
  std::shared_ptr<const tissue::SurfaceTwistTable> table_;  // immutable: both threads
  const geometry::TriMesh* rest_ = nullptr;
  double max_twist_ = 0;  // rad
  // Haptic thread: the current grasp's.
  double grasp_stiffness_ = 0, grasp_capacity_ = 0;  // N·m/rad, N·m
  // Deformation thread.
  std::unique_ptr<tissue::ReducedTwistModel> grasp_;
  uint64_t grasp_id_ = 0;
  bool fallback_ = false;
  double applied_torque_ = 0;
};

}  // namespace vsurg::sim
