// What crosses the haptic boundary: a stylus sample in, a force command out.
//
// Units: s, m, N, N/m, rad, N·m. Positions are in the scene frame. These are plain values; the
// network layer (proto/) converts them to and from its wire messages.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vsurg::haptics {

using Vec3 = Eigen::Vector3d;

enum StylusButton : uint32_t {
  kButtonGrasp = 1u << 0,  // held: grasp (and twist) the tissue under the tip
};

struct StylusSample {
  double time = 0;                                                  // s, the station's clock
  Vec3 position = Vec3::Zero();                                     // m, the tip (HIP)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // stylus frame in scene frame
  uint32_t buttons = 0;                                             // StylusButton bits
};

// F(x) = force0 + jacobian · (x − position0): what a station renders between server updates
// (OpenSurgSim's virtual coupler sends the same).
struct LocalModel {
  Vec3 force0 = Vec3::Zero();                          // N
  Vec3 position0 = Vec3::Zero();                       // m
  Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();  // N/m, ∂F/∂x (negative semi-definite)

  Vec3 ForceAt(const Vec3& x) const { return force0 + jacobian * (x - position0); }
};

// Safety and interaction events, as bits (several may be set by one sample).
enum HapticEvent : uint32_t {
  kEventNonFiniteInput = 1u << 0,    // the sample had NaN or infinite values: zero force
  kEventOutOfWorkspace = 1u << 1,    // the tip left the device workspace: zero force
  kEventForceClamped = 1u << 2,      // the requested force exceeded the device maximum
  kEventRateLimited = 1u << 3,       // the force changed faster than the device allows
  kEventGated = 1u << 4,             // output held at zero until the request stays small (start-up)
  kEventStiffnessClamped = 1u << 5,  // the local model was stiffer than the device allows
  kEventOverload = 1u << 6,          // the tissue was loaded past its capacity (coil model)
  kEventGraspStart = 1u << 7,
  kEventGraspEnd = 1u << 8,
  // The station's clock jumped (forward by more than sim::kMaxClockStepS, or backwards): the
  // session's trial clock advanced by at most that bound, so one sample's work stays bounded.
  kEventClockJump = 1u << 9,
  // The contact is where the reduced model has no precomputed response (e.g. next to the fixed
  // support): the nearest precomputed contact answered, so the force is bounded but less exact.
  kEventOutsideModel = 1u << 10,
};

struct ForceCommand {
  double time = 0;            // s, the sample's time echoed
  Vec3 force = Vec3::Zero();  // N, after the device limits
  LocalModel local;           // consistent with `force` at the sample position
  bool contact = false;       // the proxy is on the surface
  bool grasping = false;
  Vec3 proxy = Vec3::Zero();  // m, surface contact point (the tip when free)
  double twist = 0;           // rad, imposed twist while grasping
  double torque = 0;          // N·m, the tissue's answer to it
  double score = 0;           // 0–10, the trial's score so far (updated every few samples)
  uint32_t events = 0;        // HapticEvent bits
};

}  // namespace vsurg::haptics
