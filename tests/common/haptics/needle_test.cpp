// NeedleModel (common/haptics/needle.h): the stiffness law and the pop, Karnopp's friction on
// the shaft, the cutting front, the tract's reuse, the tissue holding the needle across, and
// the model's passivity over a loop; and the station's copy of it, corrected by the answers.
#include "common/haptics/needle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "common/haptics/needle_contact.h"

namespace vsurg::haptics {
namespace {

// Skin 2 mm, fat 10 mm, muscle to the bottom; a vessel of radius 4 mm, 20 mm deep, along y.
NeedleTissueSpec Layered() {
  NeedleTissueSpec s;
  s.surface_z = 0;
  s.layers = {
      {"skin", 0.002, {100, 20000, 1.5}, 30, 20, 100, 0.8, 2000},
      {"fat", 0.010, {60, 0, 0.2}, 6, 4, 40, 0.15, 800},
      {"muscle", 0.05, {150, 10000, 1.0}, 20, 14, 100, 0.5, 2500},
  };
  s.has_target = true;
  s.target.centre = {0, 0, -0.020};
  s.target.axis = Vec3::UnitY();
  s.target.radius = 0.004;
  s.target.wall = {200, 0, 0.6};
  return s;
}

const Vec3 kDown = -Vec3::UnitZ();

// Drives the tip straight down from 5 mm above the skin to `to_z` at `speed` m/s, 1 kHz; calls
// `each` after every step.
template <class F>
void Descend(NeedleModel& m, double from_z, double to_z, double speed, F each,
             const Vec3& axis = kDown, double x = 0) {
  const double dt = 1e-3, step = speed * dt * (to_z < from_z ? -1 : 1);
  const int n = static_cast<int>(std::round((to_z - from_z) / step));
  for (int i = 1; i <= n; ++i) each(m.Step({x, 0, from_z + i * step}, axis, dt));
}

TEST(NeedleTest, TheSkinPressesBackByItsLawUntilItsPunctureForceThenGivesWay) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  double last_before = 0, first_after = -1, depth_at_pop = -1;
  Descend(*m, 0.005, -0.012, 0.01, [&](const NeedleForce& f) {
    if (depth_at_pop < 0 && !f.popped && f.in_tissue) {
      const double w = f.depth;
      EXPECT_NEAR(f.force.z(), 100 * w + 20000 * w * w, 1e-9);  // a1·w + a2·w², up the tract
      last_before = f.force.z();
    }
    if (f.popped && depth_at_pop < 0) depth_at_pop = f.depth, first_after = f.force.z();
  });
  // 20000 w² + 100 w = 1.5 at w = 6.42 mm; the step is 10 µm.
  ASSERT_GT(depth_at_pop, 0);
  EXPECT_NEAR(depth_at_pop, (-100 + std::sqrt(100.0 * 100 + 4 * 20000 * 1.5)) / 40000, 2e-5);
  EXPECT_GT(last_before, 1.45);
  EXPECT_LT(first_after, 0.5 * last_before);  // the pop: the force falls at once
  EXPECT_EQ(m->state().phase, NeedleState::Phase::kInserted);
}

TEST(NeedleTest, ADescentPopsEachBoundaryInTurnEntersTheVesselAndBreachesItsBackWall) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  int pops = 0, entered = 0, breached = 0;
  bool was_in_target = false;
  Descend(*m, 0.005, -0.040, 0.01, [&](const NeedleForce& f) {
    pops += f.popped, entered += f.entered_target, breached += f.breached_back_wall;
    was_in_target = was_in_target || f.in_target;
    EXPECT_TRUE(f.force.allFinite());
  });
  // Skin, fat, muscle (its fascia at 12 mm: the vessel spans 16-24 mm), the front wall, the back.
  EXPECT_EQ(pops, 5);
  EXPECT_EQ(entered, 1);
  EXPECT_EQ(breached, 1);
  EXPECT_TRUE(was_in_target);
  EXPECT_EQ(m->punctures(), 5u);
  ASSERT_EQ(m->boundary_count(), 5);
  EXPECT_NEAR(m->boundary(3).depth, 0.016, 1e-9);
  EXPECT_NEAR(m->boundary(4).depth, 0.024, 1e-9);
}

TEST(NeedleTest, AnObliqueTractMeetsTheLayersAndTheVesselWhereTheLineCrossesThem) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  const Vec3 axis = Vec3(std::sin(0.5), 0, -std::cos(0.5));  // 28.6° from the normal, in x-z
  const Vec3 entry(-0.010, 0, 0);
  m->Step(entry - 0.002 * axis, axis, 1e-3);
  m->Step(entry + 0.0001 * axis, axis, 1e-3);
  ASSERT_EQ(m->state().phase, NeedleState::Phase::kTouching);
  ASSERT_EQ(m->boundary_count(), 5);
  EXPECT_NEAR(m->boundary(1).depth, 0.002 / std::cos(0.5), 1e-9);
  EXPECT_NEAR(m->boundary(2).depth, 0.012 / std::cos(0.5), 1e-9);
  // The line passes the vessel's axis (x = 0, z = −20 mm) at the distance h of the centre from
  // it, nearest at t along it: the walls at t ∓ √(R² − h²).
  const Vec3 to_centre = Vec3(0, 0, -0.020) - entry;
  const double t = to_centre.dot(axis), h = (to_centre - t * axis).norm();
  ASSERT_LT(h, 0.004);
  EXPECT_NEAR(m->boundary(3).depth, t - std::sqrt(0.004 * 0.004 - h * h), 1e-9);
  EXPECT_NEAR(m->boundary(4).depth, t + std::sqrt(0.004 * 0.004 - h * h), 1e-9);
  EXPECT_EQ(m->boundary(3).role, NeedleBoundary::kRoleTargetFront);
  // 10 mm further along x the same angle misses it: the layers alone.
  auto miss = NeedleModel::Create(Layered());
  miss->Step(entry + Vec3(-0.010, 0, 0) - 0.002 * axis, axis, 1e-3);
  miss->Step(entry + Vec3(-0.010, 0, 0) + 0.0001 * axis, axis, 1e-3);
  EXPECT_EQ(miss->boundary_count(), 3);
}

TEST(NeedleTest, TheShaftSticksWithinTheStaticLimitAndSlidesAtTheSlidingOneBothWays) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  Descend(*m, 0.005, -0.011, 0.01, [](const NeedleForce&) {});  // in the fat, 11 mm deep
  // Drawn back off the cutting front (its spring, 0.15 N / 300 N/m = 0.5 mm), held, then pushed
  // 0.1 mm deeper: the anchor's spring, inside the static limit (D·len = 0.108 N).
  Descend(*m, -0.011, -0.010, 0.01, [](const NeedleForce&) {});
  NeedleForce held;
  for (int i = 0; i < 100; ++i) held = m->Step({0, 0, -0.010}, kDown, 1e-3);
  // The withdrawal's sliding friction stays held by the static limit (the tissue dragged back).
  EXPECT_LT(held.force.z(), 0);
  const NeedleForce stuck = m->Step({0, 0, -0.0101}, kDown, 1e-3);
  EXPECT_EQ(stuck.cutting_force, 0);
  EXPECT_NEAR(stuck.force.z() - held.force.z(), 300 * 0.0001, 1e-9);  // stuck: k_s·Δs
  // Withdrawn at 10 mm/s from 10.1 to 5 mm: sliding friction only, opposed to the motion.
  double slide = 0;
  int n = 0;
  Descend(*m, -0.0101, -0.005, 0.01, [&](const NeedleForce& f) {
    EXPECT_EQ(f.cutting_force, 0);
    if (f.depth < 0.009 && f.depth > 0.007) slide += f.force.z(), ++n;
  });
  ASSERT_GT(n, 0);
  slide /= n;
  // At ~8 mm: 2 mm of skin and 6 mm of fat; C·len + b·v·len.
  const double c = 20 * 0.002 + 4 * 0.006, b = (100 * 0.002 + 40 * 0.006) * 0.01;
  EXPECT_NEAR(slide, -(c + b), 0.15 * (c + b));
}

TEST(NeedleTest, CuttingResistsOnlyTheTissueNotYetCut) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  double cutting_first = 0;
  Descend(*m, 0.005, -0.010, 0.005,
          [&](const NeedleForce& f) { cutting_first = std::max(cutting_first, f.cutting_force); });
  EXPECT_NEAR(cutting_first, 0.15, 1e-9);  // the fat's cutting force reached
  Descend(*m, -0.010, -0.006, 0.005, [](const NeedleForce&) {});
  double cutting_again = 0;
  Descend(*m, -0.006, -0.009, 0.005,
          [&](const NeedleForce& f) { cutting_again = std::max(cutting_again, f.cutting_force); });
  EXPECT_EQ(cutting_again, 0);  // back along the cut: friction only
}

TEST(NeedleTest, AReinsertionAlongTheTractEntersWithoutAPopAndANewPathPuncturesAgain) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  Descend(*m, 0.005, -0.010, 0.01, [](const NeedleForce&) {});
  ASSERT_EQ(m->punctures(), 2u);  // skin and fat
  Descend(*m, -0.010, 0.005, 0.01, [](const NeedleForce&) {});
  ASSERT_EQ(m->state().phase, NeedleState::Phase::kFree);
  int pops = 0;
  double peak = 0;
  Descend(*m, 0.005, -0.009, 0.01, [&](const NeedleForce& f) {
    pops += f.popped;
    peak = std::max(peak, f.force.z());
  });
  EXPECT_EQ(pops, 0);
  EXPECT_LT(peak, 0.2);  // friction, not the skin's 1.5 N
  EXPECT_EQ(m->state().tract, 1u);
  Descend(*m, -0.009, 0.005, 0.01, [](const NeedleForce&) {});
  Descend(
      *m, 0.005, -0.009, 0.01, [&](const NeedleForce& f) { pops += f.popped; }, kDown, 0.004);
  EXPECT_EQ(pops, 2);  // 4 mm away: a new path, skin and fat again
  EXPECT_EQ(m->state().tract, 2u);
  EXPECT_EQ(m->punctures(), 4u);
}

// Turns the needle about the skin's hole at `entry`, its tip `depth` along it, from `from` to `to`
// (unit axes) over `steps` steps at 1 kHz; calls `each` after every step.
template <class F>
void Pivot(NeedleModel& m, const Vec3& entry, double depth, const Vec3& from, const Vec3& to,
           int steps, F each) {
  for (int i = 1; i <= steps; ++i) {
    const Vec3 u = from + (to - from) * (static_cast<double>(i) / steps);
    each(m.Step(entry + depth * u.normalized(), u.normalized(), 1e-3));
  }
}

// Advances the needle along `u` from `depth` to `to` at 10 mm/s, 1 kHz.
template <class F>
void Advance(NeedleModel& m, const Vec3& entry, const Vec3& u, double depth, double to, F each) {
  const int n = static_cast<int>(std::round((to - depth) / 1e-5));
  for (int i = 1; i <= n; ++i) each(m.Step(entry + (depth + i * 1e-5) * u, u, 1e-3));
}

// A miss: vertical 12 mm beside the vessel's axis, down to 19 mm (skin, fat and the muscle's
// fascia punctured, the vessel passed by).
const Vec3 kBesideTheVessel(-0.012, 0, 0);
Expected<NeedleModel> InsertedBesideTheVessel() {
  auto m = NeedleModel::Create(Layered());
  if (!m.ok()) return m;
  m->Step(kBesideTheVessel + Vec3(0, 0, 0.005), kDown, 1e-3);
  Descend(
      *m, 0.005, -0.019, 0.01, [](const NeedleForce&) {}, kDown, kBesideTheVessel.x());
  return m;
}

// A miss corrected as a clinician does: drawn back into the fat, angled toward the vessel and
// advanced, the needle pivots about the skin's hole. No new pop at the skin; the fascia and the
// vessel's wall on the new line pop; the first tract is kept; the new one aims at the vessel.
TEST(NeedleTest, ANeedleDrawnBackUnderTheSkinIsRedirectedAboutItsHoleToTheTarget) {
  const Vec3 entry = kBesideTheVessel;
  auto m = InsertedBesideTheVessel();
  ASSERT_TRUE(m.ok());
  ASSERT_EQ(m->punctures(),
            3u);  // skin, fat, the muscle's fascia (popped 17.6 mm down): 12 mm beside the vessel
  double middle = 0, deviation = 0;
  int needed = 0;
  ASSERT_TRUE(m->TargetOnTract(middle, deviation, needed));
  EXPECT_NEAR(deviation, 0.012, 1e-9);
  Descend(
      *m, -0.019, -0.006, 0.01, [](const NeedleForce&) {}, kDown, entry.x());  // into the fat
  const Vec3 aim = (Vec3(0, 0, -0.020) - entry).normalized();  // 31° from the normal
  int redirects = 0, pops = 0;
  Pivot(*m, entry, 0.006, kDown, aim, 300, [&](const NeedleForce& f) {
    redirects += f.redirected;
    EXPECT_TRUE(f.force.allFinite());
    EXPECT_LT(f.force.norm(), 0.2);  // skin and fat hold a shallow needle lightly
  });
  EXPECT_EQ(redirects, 0) << "turned in place: nothing new cut yet";
  EXPECT_EQ(m->state().tract, 1u);
  Advance(*m, entry, aim, 0.006, 0.0235, [&](const NeedleForce& f) {
    redirects += f.redirected, pops += f.popped;
    EXPECT_TRUE(f.force.allFinite());
  });
  EXPECT_EQ(redirects, 1);
  EXPECT_EQ(m->state().tract, 2u);
  EXPECT_LT((m->state().entry - entry).norm(), 1e-6) << "the same hole in the skin";
  EXPECT_GT(m->state().direction.dot(aim), std::cos(0.01));
  ASSERT_TRUE(m->TargetOnTract(middle, deviation, needed));
  EXPECT_LT(deviation, 0.0005) << "the new tract aims at the vessel";
  EXPECT_EQ(pops, 2) << "the fascia on the new line and the vessel's front wall";
  EXPECT_EQ(m->punctures(), 5u);
  EXPECT_TRUE(m->Step(entry + 0.0235 * aim, aim, 1e-3).in_target);
  const std::vector<NeedleState> tracts = m->Tracts();
  ASSERT_EQ(tracts.size(), 2u);
  EXPECT_NEAR(tracts[0].direction.dot(kDown), 1, 1e-9);
  EXPECT_EQ(tracts[1].tract, 2u);
}

// Deeper than the layer under the skin the tissue holds the needle on its tract: turning it there
// strains the tissue (the lateral spring) and never turns the tract. Turned back onto the first
// tract from the fat, the needle follows it again without a pop.
TEST(NeedleTest, ADeepNeedleIsHeldOnItsTractAndTurnedBackFollowsTheFirstTract) {
  const Vec3 entry = kBesideTheVessel;
  auto m = InsertedBesideTheVessel();
  ASSERT_TRUE(m.ok());
  const Vec3 tilted = Vec3(std::sin(0.35), 0, -std::cos(0.35));  // 20°
  int redirects = 0;
  double strain = 0;
  Pivot(*m, entry, 0.019, kDown, tilted, 200, [&](const NeedleForce& f) { strain = f.strain; });
  Advance(*m, entry, tilted, 0.019, 0.021, [&](const NeedleForce& f) {
    redirects += f.redirected;
    strain = f.strain;
  });
  EXPECT_EQ(redirects, 0);
  EXPECT_EQ(m->state().tract, 1u);
  EXPECT_GT(strain, 0.2) << "the tissue was levered";
  // Back into the fat, angled and advanced: a second tract; then turned back to vertical and
  // advanced, the first tract again (no pop: its fascia was punctured before).
  Advance(*m, entry, tilted, 0.021, 0.006, [](const NeedleForce&) {});
  Pivot(*m, entry, 0.006, kDown, tilted, 100, [](const NeedleForce&) {});
  Advance(*m, entry, tilted, 0.006, 0.008,
          [&](const NeedleForce& f) { redirects += f.redirected; });
  ASSERT_EQ(redirects, 1);
  ASSERT_EQ(m->state().tract, 2u);
  Pivot(*m, entry, 0.008, tilted, kDown, 100, [](const NeedleForce&) {});
  int pops = 0;
  Advance(*m, entry, kDown, 0.008, 0.015,
          [&](const NeedleForce& f) { redirects += f.redirected, pops += f.popped; });
  EXPECT_EQ(redirects, 2);
  EXPECT_EQ(m->state().tract, 1u);
  EXPECT_EQ(pops, 0);
  EXPECT_EQ(m->state().passed, 3u);
}

// A hard case on purpose: the needle driven at a hand's top speed (1 and 3 m/s: 1 to 3 mm per
// servo cycle) straight through every layer, the vessel and its back wall, and drawn out as fast.
// Every boundary still gives way once, in order (one per step), the force stays finite and below
// what the laws allow (the largest puncture force, the shaft's whole friction at that speed and
// the cutting force together), and the tract is left when the needle is out.
TEST(NeedleTest, AtAHandsTopSpeedEveryBoundaryPopsOnceAndTheForceStaysBounded) {
  for (double speed : {1.0, 3.0}) {
    SCOPED_TRACE("speed " + std::to_string(speed) + " m/s");
    auto m = NeedleModel::Create(Layered());
    ASSERT_TRUE(m.ok());
    m->Step({0, 0, 0.005}, kDown, 1e-3);
    // Shaft held at most 60 mm: skin 2, fat 10, muscle 48 (N/m per metre of shaft), at `speed`.
    const double friction =
        0.002 * (20 + 100 * speed) + 0.010 * (4 + 40 * speed) + 0.048 * (14 + 100 * speed);
    const double bound = 1.5 + friction + 0.8;  // the skin's puncture, the friction, the cutting
    int pops = 0;
    double largest = 0;
    const auto each = [&](const NeedleForce& f) {
      ASSERT_TRUE(f.force.allFinite());
      pops += f.popped;
      largest = std::max(largest, f.force.norm());
    };
    Descend(*m, 0.005, -0.040, speed, each);
    EXPECT_EQ(pops, 5);
    EXPECT_EQ(m->punctures(), 5u);
    Descend(*m, -0.040, 0.005, speed, each);
    EXPECT_EQ(m->state().phase, NeedleState::Phase::kFree);
    EXPECT_EQ(m->Tracts().size(), 1u);
    std::printf("%.0f m/s: largest force %.2f N (bound %.2f N)\n", speed, largest, bound);
    EXPECT_LT(largest, bound);
  }
}

TEST(NeedleTest, TheTissueHoldsTheNeedleAcrossItsTract) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  Descend(*m, 0.005, -0.010, 0.01, [](const NeedleForce&) {});
  const NeedleForce f = m->Step({0.001, 0, -0.010}, kDown, 1e-3);
  const double k = 2000 * 0.002 + 800 * 0.008;  // N/m: skin and fat held
  EXPECT_NEAR(f.force.x(), -k * 0.001, 1e-9);
  EXPECT_NEAR(f.lateral, 0.001, 1e-12);
  EXPECT_NEAR(f.strain, 0.1, 1e-9);
}

TEST(NeedleTest, ANeedleTooFlatToTheSkinSlidesOnItAndNeverEnters) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  const Vec3 flat = Vec3(std::cos(0.1), 0, -std::sin(0.1));  // 84° from the normal
  m->Step({0, 0, 0.005}, flat, 1e-3);
  int pops = 0;
  Descend(
      *m, 0.005, -0.015, 0.01, [&](const NeedleForce& f) { pops += f.popped; }, flat);
  EXPECT_EQ(pops, 0);
  EXPECT_NE(m->state().phase, NeedleState::Phase::kInserted);
}

TEST(NeedleTest, OverALoopInAndOutTheHandGivesTheTissueEnergyAndIsNeverGivenAny) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  double work_on_hand = 0, z_prev = 0.005;
  Vec3 f_prev = m->Step({0, 0, z_prev}, kDown, 1e-3).force;
  for (int cycle = 0; cycle < 3; ++cycle)
    for (double to : {-0.018, -0.004, -0.026, 0.005}) {
      Descend(*m, z_prev, to, 0.02, [&](const NeedleForce& f) {
        work_on_hand += f_prev.z() * (0.02e-3 * (to < z_prev ? -1 : 1));
        f_prev = f.force;
      });
      z_prev = to;
    }
  EXPECT_LT(work_on_hand, 0);  // the pops and the friction took energy; none came back
  EXPECT_TRUE(f_prev.allFinite());
}

TEST(NeedleTest, NonFiniteInputAnswersZeroAndChangesNothing) {
  auto m = NeedleModel::Create(Layered());
  ASSERT_TRUE(m.ok());
  m->Step({0, 0, 0.005}, kDown, 1e-3);
  Descend(*m, 0.005, -0.004, 0.01, [](const NeedleForce&) {});
  const NeedleState before = m->state();
  const double nan = std::nan("");
  EXPECT_EQ(m->Step({nan, 0, 0}, kDown, 1e-3).force, Vec3::Zero());
  EXPECT_EQ(m->Step({0, 0, -0.004}, Vec3(nan, 0, 0), 1e-3).force, Vec3::Zero());
  EXPECT_EQ(m->Step({0, 0, -0.004}, kDown, 0).force, Vec3::Zero());
  EXPECT_EQ(m->state(), before);
}

TEST(NeedleTest, ATissueOutOfRangeIsRefusedByName) {
  NeedleTissueSpec s = Layered();
  s.layers[1].top.puncture = 0;
  auto m = NeedleModel::Create(s);
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().field, "needle.layers[1].top.puncture");
  s = Layered();
  s.layers[2].friction_sliding = 30;  // above its static 20
  EXPECT_EQ(NeedleModel::Create(s).error().field, "needle.layers[2].friction_sliding");
  s = Layered();
  s.target.centre.z() = -0.002;  // its wall above the skin
  EXPECT_EQ(NeedleModel::Create(s).error().field, "needle.target.depth");
  s = Layered();
  s.layers.clear();
  EXPECT_EQ(NeedleModel::Create(s).error().field, "needle.layers");
}

}  // namespace
}  // namespace vsurg::haptics

namespace vsurg::haptics {
namespace {

// The station's server a round trip (300 datagrams) behind: it steps every sample as it comes and
// the station hears, with each new sample, the answer about the one 300 before.
struct ServerBehind {
  explicit ServerBehind(NeedleModel m) : model(std::move(m)) {
    answer.kind = LocalModel::Kind::kNeedle;
  }
  NeedleModel model;
  std::vector<NeedleState> states;
  LocalModel answer;
  // The server steps sample `seq` (1, 2, …); the station gets the answer about seq − 300.
  void Step(NeedleContact& station, uint64_t seq, const Vec3& tip, const Vec3& axis) {
    model.Step(tip, axis, 1e-3);
    states.push_back(model.state());
    if (seq > 300) {
      answer.needle = states[seq - 301];
      station.Answer(answer, seq - 300);
    }
  }
};

// The station's needle (needle_contact.h): its own model pops on the crossing cycle; an answer
// about a datagram before that change does not undo it; a later one that disagrees is taken.
TEST(NeedleContactTest, AStationPopsOnItsOwnAndTakesOnlyANewerAnswersWord) {
  auto spec = std::make_shared<const NeedleTissueSpec>(Layered());
  NeedleContact station(spec);
  auto model = NeedleModel::Create(*spec);
  ASSERT_TRUE(station.active() && model.ok());
  ServerBehind server(std::move(*model));
  uint64_t seq = 0;
  double before = 0, after = 0;
  for (int i = 0; i <= 1200; ++i) {
    const Vec3 tip(0, 0, 0.002 - 1e-5 * i);  // down at 10 mm/s to 10 mm deep
    server.Step(station, ++seq, tip, kDown);
    const Vec3 f = station.Render(tip, kDown, seq);
    if (station.local_pops() == 0) before = f.z();
    if (station.local_pops() == 1 && after == 0) after = f.z();
  }
  EXPECT_GT(before, 1.4);  // the skin's law up to its puncture force, felt locally
  EXPECT_LT(after, 0.5);   // and the pop on the same cycle as the server's (no answer yet)
  EXPECT_EQ(station.local_pops(), 2u);   // skin, fat
  EXPECT_EQ(station.corrections(), 0u);  // the answers agreed once they caught up
  EXPECT_EQ(station.model()->state().passed, server.model.state().passed);
  // A server that says otherwise about a datagram after the station's change is believed.
  LocalModel otherwise = server.answer;
  otherwise.needle = server.model.state();
  otherwise.needle.passed = 1;
  station.Answer(otherwise, seq);
  EXPECT_EQ(station.corrections(), 1u);
  EXPECT_EQ(station.model()->state().passed, 1u);
}

// A redirection seen a round trip late: the station turns its tract about the skin's hole on the
// cycle the needle advances at its new angle, the server does the same a round trip later, and
// the station never takes the older answers' tract for a contradiction; both end on the same
// tract with the same punctures.
TEST(NeedleContactTest, ARedirectionIsTheStationsOwnAndTheServerAgreesARoundTripLater) {
  auto spec = std::make_shared<const NeedleTissueSpec>(Layered());
  NeedleContact station(spec);
  auto model = NeedleModel::Create(*spec);
  ASSERT_TRUE(station.active() && model.ok());
  ServerBehind server(std::move(*model));
  // Vertical into the fat 12 mm beside the vessel, back to 6 mm, turned 31° toward it, advanced.
  const Vec3 entry(-0.012, 0, 0), aim = (Vec3(0, 0, -0.020) - entry).normalized();
  std::vector<std::pair<Vec3, Vec3>> path;  // tip, axis
  for (int i = 0; i <= 1000; ++i) path.push_back({entry + Vec3(0, 0, 0.002 - 1e-5 * i), kDown});
  for (int i = 1; i <= 200; ++i) path.push_back({entry + Vec3(0, 0, -0.008 + 1e-5 * i), kDown});
  for (int i = 1; i <= 300; ++i) {
    const Vec3 u = (kDown + (aim - kDown) * (i / 300.0)).normalized();
    path.push_back({entry + 0.006 * u, u});
  }
  for (int i = 1; i <= 1200; ++i) path.push_back({entry + (0.006 + 1e-5 * i) * aim, aim});
  uint64_t seq = 0;
  int redirected_at = -1;
  for (const auto& [tip, axis] : path) {
    server.Step(station, ++seq, tip, axis);
    const uint32_t tract = station.model()->state().tract;
    EXPECT_TRUE(station.Render(tip, axis, seq).allFinite());
    if (redirected_at < 0 && tract == 1 && station.model()->state().tract == 2)
      redirected_at = static_cast<int>(seq);
  }
  EXPECT_GT(redirected_at, 1500) << "not before the needle advanced at its new angle";
  EXPECT_EQ(station.corrections(), 0u);
  EXPECT_EQ(station.model()->state().tract, server.model.state().tract);
  EXPECT_EQ(station.model()->state().tract, 2u);
  EXPECT_EQ(station.model()->state().passed, server.model.state().passed);
  EXPECT_EQ(station.local_pops(), static_cast<uint64_t>(server.model.punctures()));
}

}  // namespace
}  // namespace vsurg::haptics
