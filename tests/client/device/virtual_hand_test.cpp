#include "client/device/virtual_hand.h"

#include <cmath>

#include <gtest/gtest.h>

namespace vsurg::client {
namespace {

using Vec3 = Eigen::Vector3d;

std::vector<haptics::StylusSample> StillPlan(const Vec3& at, double seconds) {
  std::vector<haptics::StylusSample> plan;
  for (int k = 0; k <= static_cast<int>(seconds * 1000); ++k) {
    haptics::StylusSample s;
    s.time = k * 1e-3;
    s.position = at;
    plan.push_back(s);
  }
  return plan;
}

TEST(VirtualHandTest, WithNoForceTheHandStaysOnItsPlan) {
  auto hand = VirtualHandDevice::Create(StillPlan(Vec3(0.01, 0.02, 0.03), 1.0));
  ASSERT_TRUE(hand.ok());
  for (int k = 0; k <= 1000; ++k) {  // the plan's 1001 samples: 0 .. 1 s
    const haptics::StylusSample s = (*hand)->Read();
    (*hand)->WriteForce(Vec3::Zero());
    ASSERT_NEAR((s.position - Vec3(0.01, 0.02, 0.03)).norm(), 0.0, 0.06e-3);  // one count
  }
  EXPECT_TRUE((*hand)->finished());
}

TEST(VirtualHandTest, AHeldForceDisplacesTheGripByForceOverStiffness) {
  // Statics of the hand's impedance: a steady 1 N settles the hand F/K_h off its plan; with the
  // device's Coulomb friction it stops anywhere within f_c/K_h short of that.
  for (const HandImpedance grip : {RelaxedGrip(), TensedGrip()}) {
    for (const double friction : {0.0, 0.26}) {
      DeviceModel device;
      device.friction = friction;
      device.resolution = 0;
      auto hand = VirtualHandDevice::Create(StillPlan(Vec3::Zero(), 3.0), grip, device);
      ASSERT_TRUE(hand.ok());
      haptics::StylusSample s;
      for (int k = 0; k < 3000; ++k) {
        s = (*hand)->Read();
        (*hand)->WriteForce(Vec3(1.0, 0, 0));
      }
      const double expected = 1.0 / grip.stiffness;
      EXPECT_LE(s.position.x(), expected + 1e-6) << grip.stiffness << " " << friction;
      EXPECT_GE(s.position.x(), (1.0 - friction) / grip.stiffness - 1e-6)
          << grip.stiffness << " " << friction;
    }
  }
}

TEST(VirtualHandTest, ACorrectionMovesTheIntentAndANonFiniteOneIsIgnored) {
  // A hand told to correct by 2 mm settles there with no force on it (its plan stays put), the
  // trace's plan shows where it meant to be, and a NaN correction leaves the last one in place.
  DeviceModel device;
  device.friction = 0;
  device.resolution = 0;
  auto hand = VirtualHandDevice::Create(StillPlan(Vec3::Zero(), 3.0), TensedGrip(), device);
  ASSERT_TRUE(hand.ok());
  haptics::StylusSample s;
  for (int k = 0; k < 3000; ++k) {
    if (k == 100) (*hand)->Correct(Vec3(0.002, 0, 0));
    if (k == 1500) (*hand)->Correct(Vec3(std::nan(""), 0, 0));
    s = (*hand)->Read();
    (*hand)->WriteForce(Vec3::Zero());
  }
  EXPECT_NEAR(s.position.x(), 0.002, 1e-6);
  EXPECT_NEAR(s.position.y(), 0.0, 1e-9);
  const auto trace = (*hand)->trace();
  EXPECT_NEAR(trace.front().plan.x(), 0.0, 1e-12);
  EXPECT_NEAR(trace.back().plan.x(), 0.002, 1e-12);
}

TEST(VirtualHandTest, TheDeviceSaturatesAndReadsInEncoderCounts) {
  DeviceModel device;  // Touch-class: 3.3 N, 0.055 mm counts
  auto hand = VirtualHandDevice::Create(StillPlan(Vec3::Zero(), 1.0), TensedGrip(), device);
  ASSERT_TRUE(hand.ok());
  haptics::StylusSample s;
  for (int k = 0; k < 1000; ++k) {
    s = (*hand)->Read();
    (*hand)->WriteForce(Vec3(0, 0, 50.0));  // far over the limit
    const double counts = s.position.z() / device.resolution;
    ASSERT_NEAR(counts, std::round(counts), 1e-6);
  }
  // Settled at 3.3 N over the tensed grip's 540 N/m, not 50 N's worth.
  EXPECT_NEAR(s.position.z(), 3.3 / 540, 0.5 / 540);
  const auto trace = (*hand)->trace();
  ASSERT_EQ(trace.size(), 1000u);
  EXPECT_NEAR(trace.back().force.norm(), 3.3, 1e-9);
}

TEST(VirtualHandTest, BadParametersAreRefused) {
  EXPECT_FALSE(VirtualHandDevice::Create({}).ok());
  HandImpedance none{0.5, 1, 0};
  EXPECT_FALSE(VirtualHandDevice::Create(StillPlan(Vec3::Zero(), 0.1), none).ok());
  auto plan = StillPlan(Vec3::Zero(), 0.1);
  plan[3].position.x() = NAN;
  EXPECT_FALSE(VirtualHandDevice::Create(plan).ok());
  EXPECT_FALSE(GripByName("limp").ok());
}

}  // namespace
}  // namespace vsurg::client
