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
#include "common/tissue/twist_table.h"

namespace vsurg::sim {

class ReducedTwistRoom {
 public:
  static constexpr bool kPaced = false;
  static Expected<ReducedTwistRoom> Build(const RoomInputs& in);
  // Haptic thread: the axis is the centreline where it passes the grasp.
  bool StartGrasp(const GraspQuery& q, GraspFrame& f) const;
  TwistAnswer Twist(double twist) const;
  // Haptic thread, around one sample's Twist calls while grasping (a scene's "relaxation": the
  // torque relaxes while the twist is held; nothing without one): the step's length and the
  // trial's time at its end (s), the history first held over any time since the last step; the
  // twist it ended at (carries the history); the grasp let go (the elastic torque falls to 0).
  void BeginTwistStep(double dt, double now);
  void EndTwistStep(double twist);
  void ReleaseTwist(double dt, double now);
  void Save(StateWriter& w) const;
  bool Load(StateReader& r);
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
  // Haptic thread: the relaxation's internal torques, the step's length and end, the last step's
  // end (s, trial time).
  std::optional<tissue::TorqueRelaxation> relax_;
  double step_dt_ = 1e-3, step_end_ = 0, last_end_ = 0;
  tissue::TorqueRelaxation::Step step_;  // the step's decay: relax_->Over(step_dt_)
  // Deformation thread.
  double applied_torque_ = 0;
  bool applied_grasp_ = false;
};

}  // namespace vsurg::sim
