#include "common/tissue/torsion_reference.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace vsurg::tissue {
namespace {

TEST(SaintVenantTest, UniformShaftTwistsLinearly) {
  // θ(z) = T·z/(G·J), J = π·a⁴/2.
  const TaperedShaft s{0.3, 0.02, 0.02, 1e4};
  const double j = std::numbers::pi * std::pow(0.02, 4) / 2;
  for (double z : {0.0, 0.1, 0.3})
    EXPECT_NEAR(SaintVenantTwistAt(s, 0.5, z), 0.5 * z / (1e4 * j), 1e-9);
  EXPECT_NEAR(SaintVenantTwistFromGrasp(s, 0.5, 0.0), 0.5 * 0.3 / (1e4 * j), 1e-9);
}

TEST(SaintVenantTest, TaperedShaftMatchesNumericalIntegrationOfTheTwistRate) {
  const TaperedShaft s{0.25, 0.04, 0.03, 12e3};
  const double torque = 0.1;
  // Simpson's rule on dθ/dz = T/(G·π·a(z)⁴/2).
  const int n = 2000;
  auto rate = [&](double z) {
    const double a = s.radius_proximal + (s.radius_distal - s.radius_proximal) * z / s.length;
    return torque / (s.shear_modulus * std::numbers::pi * std::pow(a, 4) / 2);
  };
  double integral = rate(0) + rate(s.length);
  for (int i = 1; i < n; ++i) integral += (i % 2 ? 4 : 2) * rate(s.length * i / n);
  integral *= s.length / n / 3;
  EXPECT_NEAR(SaintVenantTwistAt(s, torque, s.length), integral, 1e-9 * integral);
  // Twist is monotone along the shaft and linear in torque.
  EXPECT_LT(SaintVenantTwistAt(s, torque, 0.1), SaintVenantTwistAt(s, torque, 0.2));
  EXPECT_NEAR(SaintVenantTwistAt(s, 2 * torque, 0.2), 2 * SaintVenantTwistAt(s, torque, 0.2),
              1e-12);
}

}  // namespace
}  // namespace vsurg::tissue
