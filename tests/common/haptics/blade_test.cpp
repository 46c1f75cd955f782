// BladeModel (common/haptics/blade.h): the puncture at the fracture criterion, the crack drawn
// at f_c = J_c t, the energy balance over a cut, the slit that offers no force, a branch, and bad
// parameters refused by name.
#include "common/haptics/blade.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace vsurg::haptics {
namespace {

BladeParams Skin() {
  BladeParams p;
  p.toughness = 1700, p.thickness = 1.2e-3, p.width = 0.3e-3;
  p.in_plane_stiffness = 1500, p.normal_stiffness = 30;
  return p;
}

// Pressed straight down at (x, y) until through; returns the largest force met on the way.
double PressThrough(BladeModel& m, double x, double y) {
  double peak = 0;
  for (int i = 1; i < 100000 && !m.through(); ++i) {
    const BladeForce f = m.Step(Vec3(x, y, -1e-6 * i));
    peak = std::max(peak, f.force.norm());
  }
  return peak;
}

TEST(BladeTest, ThePunctureComesAtTheFractureCriterionAndTheAngleRaisesIt) {
  for (double angle : {0.0, 0.5, 1.0}) {
    BladeParams p = Skin();
    p.angle = angle;
    auto m = BladeModel::Create(p);
    ASSERT_TRUE(m.ok());
    const double expected = std::sqrt(2 * 30 * 1700 * 1.2e-3 * 0.3e-3 / std::cos(angle));
    EXPECT_NEAR(m->PunctureForce(), expected, 1e-12);
    const double peak = PressThrough(*m, 0, 0);
    EXPECT_TRUE(m->through());
    EXPECT_NEAR(peak, expected, 30 * 1e-6 + 1e-9) << "angle " << angle;
  }
}

TEST(BladeTest, AStraightCutIsDrawnAtJcTimesThicknessAndTheWorkPaysForTheCrack) {
  auto m = BladeModel::Create(Skin());
  ASSERT_TRUE(m.ok());
  PressThrough(*m, -0.02, 0);
  const double fc = 1700 * 1.2e-3;
  EXPECT_NEAR(m->CuttingForce(), fc, 1e-12);
  double work = 0, x = -0.02;
  int cutting = 0;
  Vec3 last_force = Vec3::Zero();
  for (int i = 0; i < 30000; ++i) {  // 30 mm at 1 µm a step
    const double next = x + 1e-6;
    const BladeForce f = m->Step(Vec3(next, 0, -1e-3));
    work += -f.force.x() * (next - x);
    x = next;
    if (f.cutting) {
      ++cutting;
      EXPECT_NEAR(f.force.norm(), fc, 1e-9);
    }
    last_force = f.force;
  }
  // The deformation phase: the tip ran ahead of the crack by f_c / k_t before it first advanced.
  EXPECT_NEAR(m->CrackLength(), 0.030 - fc / 1500 - 0.5 * 0.3e-3, 2e-6);
  EXPECT_GT(cutting, 25000);
  // Energy: the blade's work is the crack's J_c t per metre plus the elastic energy still held.
  const double stored = 0.5 * fc * fc / 1500;
  EXPECT_NEAR(work, fc * m->CrackLength() + stored, 0.01 * work);
  EXPECT_EQ(m->segment_count(), 1) << "a straight cut is one segment";
  EXPECT_NEAR(last_force.x(), -fc, 1e-9);
}

TEST(BladeTest, BackInItsOwnSlitTheBladeMeetsNothingAndSidewaysItBranchesAtFc) {
  auto m = BladeModel::Create(Skin());
  ASSERT_TRUE(m.ok());
  PressThrough(*m, 0, 0);
  for (int i = 1; i <= 10000; ++i) m->Step(Vec3(1e-6 * i, 0, -1e-3));
  const double length = m->CrackLength();
  double last = INFINITY;
  for (int i = 10000; i >= 8700; --i) {  // ahead of the crack's end: the tissue unloads
    const BladeForce f = m->Step(Vec3(1e-6 * i, 0, -1e-3));
    EXPECT_LT(f.force.norm(), last + 1e-12) << i;
    EXPECT_FALSE(f.cutting);
    last = f.force.norm();
  }
  for (int i = 8400; i >= 2000; --i) {  // drawn back along the slit
    const BladeForce f = m->Step(Vec3(1e-6 * i, 0, -1e-3));
    EXPECT_EQ(f.force.norm(), 0.0) << i;
    EXPECT_FALSE(f.cutting);
  }
  EXPECT_EQ(m->CrackLength(), length);
  // Lifted out and pressed in again in the slit: through at once, no puncture.
  EXPECT_FALSE(m->Step(Vec3(0.002, 0, 1e-3)).through);
  const BladeForce in = m->Step(Vec3(0.002, 0, -1e-4));
  EXPECT_TRUE(in.through);
  EXPECT_FALSE(in.punctured);
  // Sideways out of the slit: the tissue resists, then a branch grows at f_c.
  double peak = 0;
  for (int i = 1; i <= 5000; ++i) {
    const BladeForce f = m->Step(Vec3(0.002, 1e-6 * i, -1e-3));
    peak = std::max(peak, f.force.norm());
    EXPECT_LE(f.force.y(), 0.0);
  }
  EXPECT_NEAR(peak, m->CuttingForce(), 1e-9);
  EXPECT_EQ(m->segment_count(), 2);
  EXPECT_GT(m->CrackLength(), length + 0.002);
}

TEST(BladeTest, OffThePatchOrNotFiniteItIsFree) {
  auto m = BladeModel::Create(Skin());
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->Step(Vec3(0.05, 0, -1e-3)).force.norm(), 0.0);
  EXPECT_EQ(m->Step(Vec3(NAN, 0, -1e-3)).force.norm(), 0.0);
  EXPECT_EQ(m->Step(Vec3(0, INFINITY, -1e-3)).force.norm(), 0.0);
  EXPECT_FALSE(m->through());
}

TEST(BladeTest, BadParametersAreRefusedByName) {
  const auto field = [](auto change) {
    BladeParams p = Skin();
    change(p);
    auto m = BladeModel::Create(p);
    return m.ok() ? std::string("ok") : m.error().field;
  };
  EXPECT_EQ(field([](BladeParams& p) { p.toughness = 0; }), "toughness");
  EXPECT_EQ(field([](BladeParams& p) { p.toughness = -5; }), "toughness");
  EXPECT_EQ(field([](BladeParams& p) { p.width = 0; }), "width");
  EXPECT_EQ(field([](BladeParams& p) { p.thickness = NAN; }), "thickness");
  EXPECT_EQ(field([](BladeParams& p) { p.angle = 1.5; }), "angle");
  EXPECT_EQ(field([](BladeParams& p) { p.in_plane_stiffness = 0; }), "in_plane_stiffness");
  EXPECT_EQ(field([](BladeParams&) {}), "ok");
}

// A circle cut all the way round: the blade reaches the start of its own cut while still loading
// its front, and the ligament between them is cut, so the cut is one closed loop.
TEST(BladeTest, ACircleClosesOnItsStart) {
  auto m = BladeModel::Create(Skin());
  ASSERT_TRUE(m.ok());
  const double r = 0.015;
  PressThrough(*m, r, 0);
  const int n = 20000;
  for (int i = 0; i <= n; ++i) {
    const double a = 2 * std::numbers::pi * 1.05 * i / n;
    m->Step(Vec3(r * std::cos(a), r * std::sin(a), -1e-3));
  }
  bool closed = false;
  for (int i = 1; i < m->segment_count(); ++i) {
    const auto& s = m->segment(i);
    closed = closed || std::hypot(s.bx - r, s.by) < 0.5 * Skin().width + 1e-9;
  }
  EXPECT_TRUE(closed) << "no segment reaches the cut's start";
  EXPECT_NEAR(m->CrackLength(), 2 * std::numbers::pi * r, 0.05 * 2 * std::numbers::pi * r);
  EXPECT_LT(m->segment_count(), 400);
}

}  // namespace
}  // namespace vsurg::haptics
