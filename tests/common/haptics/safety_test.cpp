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
  auto f =
      SafetyFilter::Create(TouchLimits(), {.gate_force = 0.2, .gate_cycles = 0, .ramp_time = 0});
  uint32_t armed = 0;
  f->Filter(Vec3::Zero(), 1e-3, armed);  // armed, no ramp
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
  // The contact's damping ahead of the tool: kept when it is one, zeroed when it is not.
  m.contact_damping = 1.5;
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_EQ(m.contact_damping, 1.5);
  for (double bad : {-1.0, double(NAN), double(INFINITY)}) {
    m.contact_damping = bad;
    ev = 0;
    f->LimitLocalModel(m, Vec3::Zero(), ev);
    EXPECT_EQ(m.contact_damping, 0.0) << bad;
    EXPECT_TRUE(ev & kEventNonFiniteInput) << bad;
  }
  // A grasp's exact model with anything not finite is dropped for its tangent (g, kept).
  m.kind = LocalModel::Kind::kGrasp;
  m.dforce_dtwist = Vec3(0, -2, 0);
  m.has_twist_model = true;
  m.force_per_torque = Vec3(0, -200, 0);
  ev = 0;
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_TRUE(m.has_twist_model);
  EXPECT_FALSE(ev & kEventNonFiniteInput);
  m.torque_steps[5] = NAN;
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_FALSE(m.has_twist_model);
  EXPECT_EQ(m.kind, LocalModel::Kind::kGrasp);
  EXPECT_EQ(m.dforce_dtwist, Vec3(0, -2, 0));
  EXPECT_TRUE(ev & kEventNonFiniteInput);
}

// A station extrapolates F₀ + J·(x − x₀) between updates: while the gate holds the force back,
// the stiffness must be held back too, or a session that starts (or is re-placed after a node's
// loss) with the tip in tissue renders J·Δx up to the device limit as the hand moves.
TEST(SafetyFilterTest, WhileGatedOrRampingTheLocalStiffnessIsHeldBackLikeTheForce) {
  auto f =
      SafetyFilter::Create(TouchLimits(), {.gate_force = 0.2, .gate_cycles = 10, .ramp_time = 0.1});
  uint32_t ev = 0;
  LocalModel m;
  m.jacobian = -300.0 * Eigen::Matrix3d::Identity();
  const Vec3 out = f->Filter(Vec3(0, 0, 2), 1e-3, ev);  // deep in tissue: gated
  EXPECT_EQ(out, Vec3::Zero());
  f->LimitLocalModel(m, out, ev);
  EXPECT_EQ(m.jacobian, Eigen::Matrix3d::Zero());
  for (int i = 0; i < 10; ++i) f->Filter(Vec3::Zero(), 1e-3, ev);  // quiet: armed
  f->Filter(Vec3(0, 0, 0.1), 0.05, ev);  // half-way through the 0.1 s ramp
  m.jacobian = -300.0 * Eigen::Matrix3d::Identity();
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_NEAR(m.jacobian(2, 2), -300.0 * 0.051 / 0.1, 1e-9);  // armed 1 ms, then 50 ms more
  f->Disarm();
  m.jacobian = -300.0 * Eigen::Matrix3d::Identity();
  f->LimitLocalModel(m, Vec3::Zero(), ev);
  EXPECT_EQ(m.jacobian, Eigen::Matrix3d::Zero());
}

// The clamp holds in the arithmetic a check uses: |out| ≤ max_force exactly, for requests where
// scaling by max/|v| alone lands an ulp above the limit.
TEST(SafetyFilterTest, AClampedForceIsWithinTheLimitExactly) {
  const DeviceLimits limits = TouchLimits();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10, 10);
  int overshooting = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 v(u(rng), u(rng), u(rng));
    if (v.norm() <= limits.max_force) continue;
    overshooting += (v * (limits.max_force / v.norm())).norm() > limits.max_force;
    auto f = SafetyFilter::Create(limits, {.gate_force = 0.2, .gate_cycles = 0, .ramp_time = 0});
    uint32_t ev = 0;
    f->Filter(Vec3::Zero(), 1e-3, ev);
    const Vec3 out = f->Filter(v, 1.0, ev);  // a long step: no rate limit
    ASSERT_LE(out.norm(), limits.max_force) << v.transpose();
    EXPECT_GT(out.norm(), limits.max_force - 1e-12);
  }
  EXPECT_GT(overshooting, 0) << "no request overshot when scaled: the test checks nothing";
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
