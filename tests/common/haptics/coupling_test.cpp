#include "common/haptics/coupling.h"

#include <gtest/gtest.h>

namespace vsurg::haptics {
namespace {

TEST(SpringDamperCouplingTest, ForceIsStiffnessTimesOffsetPlusDampingTimesRate) {
  auto c = SpringDamperCoupling::Create(400.0, 2.0);
  ASSERT_TRUE(c.ok());
  // 2 mm below the surface (SCP above HIP), sinking at 10 mm/s: 0.8 N up, damped by 0.02 N.
  const Eigen::Vector3d f = c->Force(Eigen::Vector3d(0, 0, 0.002), Eigen::Vector3d(0, 0, 0.01));
  EXPECT_NEAR(f.z(), 400 * 0.002 + 2 * 0.01, 1e-15);
  EXPECT_EQ(f.x(), 0.0);
}

TEST(SpringDamperCouplingTest, NonFiniteInputGivesZeroForce) {
  auto c = SpringDamperCoupling::Create(400.0, 2.0);
  EXPECT_EQ(c->Force(Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::Zero()), Eigen::Vector3d::Zero());
  EXPECT_EQ(c->Force(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, INFINITY, 0)),
            Eigen::Vector3d::Zero());
}

TEST(SpringDamperCouplingTest, NegativeOrNonFiniteGainsAreRejected) {
  EXPECT_EQ(SpringDamperCoupling::Create(-1.0, 0.0).error().field, "stiffness");
  EXPECT_EQ(SpringDamperCoupling::Create(1.0, NAN).error().field, "damping");
}

}  // namespace
}  // namespace vsurg::haptics
