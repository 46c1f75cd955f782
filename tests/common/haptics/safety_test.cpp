#include "common/haptics/safety.h"

#include <random>

#include <gtest/gtest.h>

namespace vsurg::haptics {
namespace {

TEST(SafetyFilterTest, GatesUntilQuietThenRampsIn) {
  auto f = SafetyFilter::Create(TouchLimits(), {0.2, 5, 0.01});
  ASSERT_TRUE(f.ok());
  uint32_t ev = 0;
  // A large request at start-up is held at zero: no kick.
  for (int i = 0; i < 20; ++i) EXPECT_EQ(f->Filter(Vec3(0, 0, 2.0), 1e-3, ev), Vec3::Zero());
  EXPECT_TRUE(ev & kEventGated);
  EXPECT_FALSE(f->armed());
  // Five quiet samples arm it; then the output ramps over 10 ms.
  for (int i = 0; i < 5; ++i) f->Filter(Vec3(0, 0, 0.1), 1e-3, ev);
  EXPECT_TRUE(f->armed());
  double prev = 0;
  for (int i = 0; i < 30; ++i) {
    ev = 0;
    const double now = f->Filter(Vec3(0, 0, 1.0), 1e-3, ev).z();
    EXPECT_GE(now, prev - 1e-12);
    prev = now;
  }
  EXPECT_NEAR(prev, 1.0, 1e-12);
}

TEST(SafetyFilterTest, ClampsMagnitudeAndRate) {
  DeviceLimits l = OmniLimits();
  l.max_force_rate = 100;  // N/s
  auto f = SafetyFilter::Create(l, {1e9, 0, 0});
  uint32_t ev = 0;
  Vec3 out = f->Filter(Vec3(0, 0, 10), 1e-3, ev);
  EXPECT_NEAR(out.norm(), 0.1, 1e-12);  // 100 N/s × 1 ms
  EXPECT_TRUE(ev & kEventRateLimited);
  for (int i = 0; i < 100; ++i) out = f->Filter(Vec3(0, 0, 10), 1e-3, ev);
  EXPECT_NEAR(out.norm(), 3.3, 1e-12);
  EXPECT_TRUE(ev & kEventForceClamped);
}

TEST(SafetyFilterTest, AdversarialInputNeverExceedsTheLimits) {
  const DeviceLimits l = TouchLimits();
  auto f = SafetyFilter::Create(l, {0.2, 3, 0.005});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> big(-1e6, 1e6), dts(-1e-3, 5e-3);
  Vec3 prev = Vec3::Zero();
  for (int i = 0; i < 100000; ++i) {
    Vec3 req(big(rng), big(rng), big(rng));
    if (i % 97 == 0) req.x() = NAN;
    if (i % 89 == 0) req.y() = INFINITY;
    double dt = dts(rng);
    if (i % 83 == 0) dt = NAN;
    uint32_t ev = 0;
    const Vec3 out = f->Filter(req, dt, ev);
    ASSERT_TRUE(out.allFinite());
    ASSERT_LE(out.norm(), l.max_force * (1 + 1e-12));
    const double step_dt = std::isfinite(dt) && dt > 0 ? dt : 1e-3;
    ASSERT_LE((out - prev).norm(), l.max_force_rate * step_dt * (1 + 1e-9) + 1e-12);
    prev = out;
  }
}

TEST(SafetyFilterTest, RejectsNonFiniteAndOutOfWorkspaceSamples) {
  auto f = SafetyFilter::Create(TouchLimits());
  StylusSample s;
  uint32_t ev = 0;
  EXPECT_TRUE(f->AcceptInput(s, ev));
  s.position.x() = NAN;
  EXPECT_FALSE(f->AcceptInput(s, ev));
  EXPECT_TRUE(ev & kEventNonFiniteInput);
  s.position = Vec3(0, 0, 2.0);  // 2 m away: outside the 1 m workspace box
  ev = 0;
  EXPECT_FALSE(f->AcceptInput(s, ev));
  EXPECT_TRUE(ev & kEventOutOfWorkspace);
  s.position.setZero();
  s.orientation.coeffs()(0) = INFINITY;
  EXPECT_FALSE(f->AcceptInput(s, ev));
}

TEST(SafetyFilterTest, LocalModelStiffnessIsClampedToTheDevice) {
  auto f = SafetyFilter::Create(TouchLimits());
  LocalModel m;
  m.jacobian = -1000.0 * Eigen::Matrix3d::Identity();
  uint32_t ev = 0;
  f->LimitLocalModel(m, Vec3(0, 0, 1), ev);
  EXPECT_NEAR(m.jacobian(0, 0), -400.0, 1e-9);
  EXPECT_TRUE(ev & kEventStiffnessClamped);
  EXPECT_EQ(m.force0, Vec3(0, 0, 1));
  m.jacobian(1, 2) = NAN;
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_TRUE(m.jacobian.allFinite());
}

TEST(SafetyFilterTest, BadLimitsAreRejected) {
  DeviceLimits l;
  l.max_force = 0;
  EXPECT_EQ(SafetyFilter::Create(l).error().field, "max_force");
  l = DeviceLimits{};
  l.workspace_max.x() = -1;
  EXPECT_EQ(SafetyFilter::Create(l).error().field, "workspace");
  EXPECT_FALSE(DeviceLimitsByName("falcon").ok());
}

}  // namespace
}  // namespace vsurg::haptics
