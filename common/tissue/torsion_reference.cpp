#include "common/tissue/torsion_reference.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vsurg::tissue {

double SaintVenantTwistAt(const TaperedShaft& s, double torque, double z) {
  z = std::clamp(z, 0.0, s.length);
  const double a0 = s.radius_proximal, a1 = s.radius_distal;
  const double k = 2.0 * torque / (std::numbers::pi * s.shear_modulus);
  const double slope = (a1 - a0) / s.length;
  // For a nearly uniform shaft the closed form cancels catastrophically; use the uniform one.
  if (std::abs(slope) * s.length < 1e-9 * a0) return k * z / (a0 * a0 * a0 * a0);
  const double az = a0 + slope * z;
  return k / (3.0 * slope) * (1.0 / (a0 * a0 * a0) - 1.0 / (az * az * az));
}

}  // namespace vsurg::tissue
