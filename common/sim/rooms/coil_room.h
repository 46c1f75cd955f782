// The coil-spring torsion model's room (the coil-spring paper; common/sim/tissue_room.h has the
// contract). The haptic thread answers a twist by the model's closed-form inverse; at each new
// grasp the deformation thread binds a deformer around it (limb mode: along the centreline; surface
// mode: geodesic rings around the grasp) and turns the surface by each new torque.
#pragma once

#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"

namespace vsurg::sim {

class CoilRoom {
 public:
  static constexpr bool kPaced = false;
  static Expected<CoilRoom> Build(const RoomInputs& in);

  // Haptic thread. Limb mode: the axis is the centreline where it passes the grasp, the lever
  // the grasp's distance from it; surface mode: the surface normal, and the scene's least lever.
  bool StartGrasp(const GraspQuery& q, GraspFrame& f) const;
  // Haptic thread: Φ → M by the inverse of the coil-spring paper eq. 3–6 (overloaded past full
  // capacity).
  TwistAnswer Twist(double twist) const;
  // Haptic thread: only a grasp deforms this model (SameGraspRequest).
  static bool SameRequest(const DeformInput& a, const DeformInput& b) {
    return SameGraspRequest(a, b);
  }
  // Deformation thread. In limb mode each update is also described as its CoilTwistShape.
  std::optional<Deformed> Deform(const DeformInput& in);

 private:
  // Both threads read these; immutable after Build (the Simulation's rest surface and
  // centreline outlive the room).
  std::shared_ptr<const tissue::CoilSpringModel> coil_;
  tissue::TwistMode mode_ = tissue::TwistMode::kLimb;
  const geometry::TriMesh* rest_ = nullptr;
  const std::vector<geometry::Vec3>* centreline_ = nullptr;
  uint64_t key_ = 0;  // limb mode: CoilLimbKey of the model, rest surface and centreline
  // Limb mode: each rest vertex's projection onto the centreline and the centreline's length (m),
  // made once: a new grasp binds its deformer without projecting the mesh again.
  std::shared_ptr<const std::vector<geometry::CentrelineProjection>> projection_;
  double length_ = 0;
  // Deformation thread.
  std::unique_ptr<tissue::CoilDeformer> deformer_;
  uint64_t seen_grasp_ = 0;
  // The grasp the deformer is bound to, and (limb mode) its arc length along the centreline, m.
  std::pair<uint64_t, double> bound_{0, 0.0};
  double applied_torque_ = 0;
  bool applied_grasp_ = false;
};

}  // namespace vsurg::sim
