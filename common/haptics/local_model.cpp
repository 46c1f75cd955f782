// LocalModel::Render (common/haptics/types.h): the station's force between server updates.
#include <cmath>
#include <numbers>

#include "common/haptics/types.h"

namespace vsurg::haptics {

Vec3 LocalModel::Render(const Vec3& x, const Eigen::Quaterniond& q, uint32_t buttons,
                        const Vec3& v) const {
  if (!x.allFinite()) return Vec3::Zero();
  Vec3 f = ForceAt(x);
  switch (kind) {
    case Kind::kLinear:
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
      if (std::isfinite(dphi)) f += dforce_dtwist * dphi;
      break;
    }
  }
  return f.allFinite() ? f : Vec3::Zero();
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
