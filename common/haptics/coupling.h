// Spring-damper force feedback at a point (the mass-spring paper §2.3): F = K·x + D·ẋ.
//
// x = SCP − HIP: from the haptic interface point (the stylus tip, which may sink into the
// tissue) to the surface contact point (the proxy that stays on the surface), m; ẋ its rate,
// m/s. K in N/m, D in N·s/m; F in N pushes the stylus back towards the surface. The paper's
// "opposite to the displacement" is the sign of the penetration HIP − SCP.
//
// Threads: any; Force() is a few multiplications, never allocates, and returns zero for any
// non-finite input, so NaN never reaches a device.
#pragma once

#include <cmath>

#include <Eigen/Core>

#include "common/core/expected.h"

namespace vsurg::haptics {

class SpringDamperCoupling {
 public:
  static Expected<SpringDamperCoupling> Create(double stiffness, double damping) {
    if (!(std::isfinite(stiffness) && stiffness >= 0)) {
      return InvalidArgument("stiffness", "coupling stiffness must be finite and ≥ 0 N/m");
    }
    if (!(std::isfinite(damping) && damping >= 0)) {
      return InvalidArgument("damping", "coupling damping must be finite and ≥ 0 N·s/m");
    }
    return SpringDamperCoupling(stiffness, damping);
  }

  Eigen::Vector3d Force(const Eigen::Vector3d& x, const Eigen::Vector3d& xdot) const {
    const Eigen::Vector3d f = stiffness_ * x + damping_ * xdot;
    return f.allFinite() ? f : Eigen::Vector3d::Zero();
  }

  double stiffness() const { return stiffness_; }
  double damping() const { return damping_; }

 private:
  SpringDamperCoupling(double k, double d) : stiffness_(k), damping_(d) {}
  double stiffness_, damping_;
};

}  // namespace vsurg::haptics
