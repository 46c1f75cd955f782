// The reduced twist model's room (the FEM's twist field per unit torque: Saint-Venant made
// exact for the limb; common/tissue/reduced.h; common/sim/tissue_room.h has the contract). Linear:
// T = Φ·dT/dΦ up to the torque capacity; the field turns the limb for the torque at the grasp
// (applied on the distal face, where the field was computed: a grasp elsewhere twists as if at
// the wrist).
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/reduced.h"

namespace vsurg::sim {

class ReducedTwistRoom {
 public:
  static constexpr bool kPaced = false;
  static Expected<ReducedTwistRoom> Build(const RoomInputs& in);
  // Haptic thread: the axis is the centreline where it passes the grasp.
  bool StartGrasp(const GraspQuery& q, GraspFrame& f) const;
  TwistAnswer Twist(double twist) const;
  // Haptic thread: only a grasp deforms this model (SameGraspRequest).
  static bool SameRequest(const DeformInput& a, const DeformInput& b) {
    return SameGraspRequest(a, b);
  }
  // Deformation thread.
  std::optional<Deformed> Deform(const DeformInput& in);

 private:
  // grasp_stiffness and torque_capacity are immutable (both threads); positions are the
  // deformation thread's.
  std::unique_ptr<tissue::ReducedTwistModel> model_;
  const std::vector<geometry::Vec3>* centreline_ = nullptr;
  // Deformation thread.
  double applied_torque_ = 0;
  bool applied_grasp_ = false;
};

}  // namespace vsurg::sim
