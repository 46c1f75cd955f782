// LocalModel::Render (common/haptics/types.h): the station's force between server updates.
#include <cmath>
#include <numbers>

#include "common/haptics/types.h"

namespace vsurg::haptics {

Vec3 CouplingPull(const Vec3& d) {
  const Vec3 f = kCouplingStiffness * d;
  const double n = f.norm();
  return n > kMaxPull ? Vec3(f * (kMaxPull / n)) : f;
}

Vec3 LocalModel::ForceAt(const Vec3& x) const {
  Vec3 f = force0 + jacobian * (x - position0);
  if (pull_gain > 0)
    f += pull_gain * (CouplingPull(pull_target - x) - CouplingPull(pull_target - position0));
  return f;
}

Vec3 LocalModel::Render(const Vec3& x, const Eigen::Quaterniond& q, uint32_t buttons,
                        const Vec3& v) const {
  if (!x.allFinite()) return Vec3::Zero();
  Vec3 f = ForceAt(x);
  switch (kind) {
    case Kind::kLinear:
    case Kind::kNeedle:  // without the needle's tissue: the answer's force (J is zero)
      break;
    case Kind::kContact:
      // Unilateral: the surface pushes, never pulls. Outside it (n·F ≤ 0) nothing is felt.
      if (!(normal.dot(f) > 0)) return Vec3::Zero();
      if (contact_damping > 0 && v.allFinite()) {
        f -= contact_damping * v.dot(normal) * normal;
        if (!(normal.dot(f) > 0)) return Vec3::Zero();  // a fast withdrawal: nothing, no pull
      }
      break;
    case Kind::kGrasp: {
      if ((buttons & kButtonGrasp) == 0) return Vec3::Zero();  // let go here, felt here
      // The twist part of the rotation since the grasp answer (swing–twist decomposition, as
      // Simulation measures the imposed twist), wrapped to (−π, π].
      const Eigen::Quaterniond rel = q.normalized() * orientation0.conjugate();
      const double dphi =
          std::remainder(2.0 * std::atan2(rel.vec().dot(axis), rel.w()), 2.0 * std::numbers::pi);
      if (!std::isfinite(dphi)) break;
      if (!has_twist_model) {
        f += dforce_dtwist * dphi;
        break;
      }
      const Eigen::Matrix3d turn = Eigen::AngleAxisd(dphi, axis).toRotationMatrix();
      // No arm: the grasp is on the axis, and the tissue's force keeps its direction.
      const Vec3 turned_u = arm.isZero(0) ? force_per_torque : Vec3(turn * force_per_torque);
      f += -jacobian * (turn * arm - arm) + torque0 * (turned_u - force_per_torque) +
           TorqueStep(dphi) * turned_u;
      break;
    }
  }
  return f.allFinite() ? f : Vec3::Zero();
}

double LocalModel::TorqueStep(double dphi) const {
  // The nodes: the offsets, with the answer's own twist (0, 0) between the two halves; beyond the
  // outermost ones the end segment's slope goes on (the curve's own slope there).
  constexpr int kNodes = kTwistSamples + 1, kHalf = kTwistSamples / 2;
  std::array<double, kNodes> at{}, step{};
  for (int i = 0, k = 0; i < kNodes; ++i) {
    if (i == kHalf) continue;
    at[i] = kTwistOffsets[k], step[i] = torque_steps[k], ++k;
  }
  int hi = 1;
  while (hi < kNodes - 1 && at[hi] < dphi) ++hi;
  const int lo = hi - 1;
  return step[lo] + (step[hi] - step[lo]) * (dphi - at[lo]) / (at[hi] - at[lo]);
}

double LocalModel::TwistFieldEnergy(const Vec3& centre, const Eigen::Quaterniond& q,
                                    uint32_t buttons) const {
  if (kind != Kind::kGrasp || (buttons & kButtonGrasp) == 0 || !centre.allFinite()) return 0;
  const double k = -jacobian.trace() / 3;  // the hold spring, N/m
  if (!(k >= 1)) return 0;                 // gated or ramping from nothing: no field either
  const double e = Render(centre, q, buttons).squaredNorm() / (2 * k);
  return std::isfinite(e) ? e : 0;
}

}  // namespace vsurg::haptics
