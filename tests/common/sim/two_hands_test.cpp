// Two hands in one cut session (Simulation::OnSecondHandStylus): the first hand's scripted blade
// cuts scenes/pattern-cut.json's circle while a second hand's grasper holds the piece up for
// counter-traction, on the session's one haptic thread. What the grasper feels, what pulling too
// hard tears, and a second device that falls silent or sends garbage mid-cut.
#include <gtest/gtest.h>

#include <cmath>

#include "common/sim/cut_trainee.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {
namespace {

Scene GraspedCutScene() {
  auto scene = LoadScene(ScenesDirectory() + "/pattern-cut.json");
  EXPECT_TRUE(scene.ok()) << (scene.ok() ? "" : scene.error().message);
  EXPECT_TRUE(scene->cut && scene->cut->grasper);
  return *scene;
}

// The second hand: the scene's scripted grasper (GrasperTrainee: onto the piece's middle, jaws
// closed, lifted `lift` m and pulled `pull` m toward −x), silent from `silent_at` s on (its device
// lost), sending a NaN tip from `garbage_at` s on, or opening its jaws at `open_at` s.
struct GrasperHand {
  double lift = 0.003, pull = 0, silent_at = 1e9, garbage_at = 1e9, open_at = 1e9;
  std::vector<haptics::StylusSample> script;
  void Plan(const Scene& scene) {
    auto planned = GrasperTrainee(scene, {.lift = lift, .pull = pull, .duration = 60});
    ASSERT_TRUE(planned.ok()) << planned.error().message;
    script = std::move(*planned);
  }
  std::optional<haptics::StylusSample> At(double t) const {
    if (t >= silent_at || script.empty()) return std::nullopt;
    const auto i = std::min(script.size() - 1, static_cast<size_t>(std::lround(t * 1000)));
    haptics::StylusSample s = script[i];
    s.time = t;
    if (t >= open_at) s.buttons = 0;
    if (t >= garbage_at) s.position.x() = std::nan("");
    return s;
  }
};

struct TwoHandsPlayed {
  scoring::TrialMetrics metrics;
  double peak_grasp = 0, grasp_at_silence = 0, grasp_after = 0;
  // N, the first hand's largest force change between two answers from `watch_from` s on.
  double max_blade_jump = 0;
  bool finite = true;
  int grasps = 0;
};

TwoHandsPlayed PlayTwoHands(const Scene& scene, GrasperHand hand, double watch_from = 0) {
  hand.Plan(scene);
  auto plan = CutTrainee(scene, TraineeStyle::kGood, 1000.0, 1);
  EXPECT_TRUE(plan.ok());
  auto sim = Simulation::Create(scene, {.threaded = false});
  EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
  TwoHandsPlayed p;
  haptics::Vec3 last = haptics::Vec3::Zero();
  (*sim)->Replay(*plan, [&](const haptics::StylusSample& s, const haptics::ForceCommand& c) {
    p.finite = p.finite && c.force.allFinite();
    if (s.time >= watch_from)
      p.max_blade_jump = std::max(p.max_blade_jump, (c.force - last).norm());
    last = c.force;
    const auto second = hand.At(s.time);
    if (!second) return;
    const haptics::ForceCommand g = (*sim)->OnSecondHandStylus(*second);
    p.finite = p.finite && g.force.allFinite() && g.local.jacobian.allFinite();
    p.peak_grasp = std::max(p.peak_grasp, g.force.norm());
    if (s.time < hand.silent_at) p.grasp_at_silence = g.force.norm();
    p.grasp_after = g.force.norm();
  });
  p.metrics = (*sim)->Metrics();
  p.grasps = (*sim)->second_hand_grasps();
  return p;
}

TEST(TwoHandsTest, TheGrasperHoldsThePieceUpAndFeelsItsPullWhileTheBladeCuts) {
  const Scene scene = GraspedCutScene();
  const TwoHandsPlayed p = PlayTwoHands(scene, {});
  EXPECT_TRUE(p.finite);
  EXPECT_EQ(p.grasps, 1);
  // The patch lifted 3 mm at its middle pulls the jaws back: tenths of a newton, under the
  // device's limit (the drill's expert: 0.98 N at its peak).
  EXPECT_GT(p.peak_grasp, 0.2);
  EXPECT_LT(p.peak_grasp, scene.haptics.limits.max_force);
  EXPECT_TRUE(p.metrics.completed);
  EXPECT_GT(p.metrics.coverage, 0.95);
  EXPECT_EQ(p.metrics.torn_length, 0);
  // Once the circle closes the piece is free in the jaws: nothing pulls them any more.
  EXPECT_LT(p.grasp_after, 0.05);
}

TEST(TwoHandsTest, AGrasperPullingTooHardTearsThePatchAndTheTrialCountsIt) {
  const Scene scene = GraspedCutScene();
  GrasperHand rough;
  rough.pull = 0.015;  // 15 mm toward the frame: past the skin's failure strain at the jaws
  const TwoHandsPlayed p = PlayTwoHands(scene, rough);
  EXPECT_TRUE(p.finite);
  EXPECT_GT(p.metrics.torn_length, 0.003);
  const TwoHandsPlayed gentle = PlayTwoHands(scene, {});
  EXPECT_LT(p.metrics.score, gentle.metrics.score);
}

TEST(TwoHandsTest, ASecondDeviceLostMidCutFadesItsHoldAndTheBladeGoesOn) {
  const Scene scene = GraspedCutScene();
  constexpr double kAt = 4.0;  // mid-cut: the blade is through and drawing
  GrasperHand lost, opened;
  lost.silent_at = kAt, opened.open_at = kAt;
  const TwoHandsPlayed p = PlayTwoHands(scene, lost, kAt);
  const TwoHandsPlayed kept = PlayTwoHands(scene, {}, kAt);
  const TwoHandsPlayed let_go = PlayTwoHands(scene, opened, kAt);
  EXPECT_TRUE(p.finite);
  EXPECT_GT(p.grasp_at_silence, 0.1);  // it was holding when it went
  // The blade's hand feels nothing of it: no force step beyond what the cut itself makes.
  EXPECT_LE(p.max_blade_jump, kept.max_blade_jump + 0.05);
  EXPECT_TRUE(p.metrics.completed);
  // A lost hand does the patch no more harm than one that opened its jaws at the same moment.
  const double edge = scene.mesh.membrane.size_x / scene.mesh.membrane.cells;
  EXPECT_LE(p.metrics.torn_length, let_go.metrics.torn_length + edge);
}

// A lifted piece let go of mid-cut falls back onto the frame's plane while the blade finishes
// the circle. The blade's load is spread over the tissue at its tip (CutMembrane::Load), so the
// nearly free piece is cut, never torn, whenever the jaws open.
TEST(TwoHandsTest, APieceLetGoOfMidCutIsCutNotTorn) {
  const Scene scene = GraspedCutScene();
  for (const double at : {3.0, 4.0, 5.0, 6.0}) {
    GrasperHand opened;
    opened.open_at = at;
    const TwoHandsPlayed p = PlayTwoHands(scene, opened);
    EXPECT_TRUE(p.finite) << "opened at " << at << " s";
    EXPECT_TRUE(p.metrics.completed) << "opened at " << at << " s";
    EXPECT_EQ(p.metrics.torn_length, 0) << "opened at " << at << " s";
  }
}

TEST(TwoHandsTest, ASecondDeviceSendingGarbageGetsZeroForceAndLetsGoSmoothly) {
  const Scene scene = GraspedCutScene();
  GrasperHand bad;
  bad.garbage_at = 4.0;
  const TwoHandsPlayed p = PlayTwoHands(scene, bad, 4.0);
  const TwoHandsPlayed kept = PlayTwoHands(scene, {}, 4.0);
  EXPECT_TRUE(p.finite);
  EXPECT_EQ(p.grasp_after, 0);  // every answer to a NaN tip is zero
  EXPECT_LE(p.max_blade_jump, kept.max_blade_jump + 0.05);
  EXPECT_TRUE(p.metrics.completed);
}

TEST(TwoHandsTest, JawsClosedAwayFromThePatchHoldNothing) {
  const Scene scene = GraspedCutScene();
  auto sim = Simulation::Create(scene, {.threaded = false});
  ASSERT_TRUE(sim.ok());
  haptics::StylusSample s;
  s.buttons = haptics::kButtonGrasp;
  for (int i = 0; i < 200; ++i) {
    s.time = i * 1e-3;
    s.position = geometry::Vec3(0, 0, 0.02);  // 2 cm above the patch: out of the jaws' reach
    (*sim)->OnStylus(s);
    const haptics::ForceCommand g = (*sim)->OnSecondHandStylus(s);
    EXPECT_EQ(g.force.norm(), 0);
    EXPECT_FALSE(g.grasping);
    (*sim)->StepDeformation();
  }
  EXPECT_EQ((*sim)->second_hand_grasps(), 0);
}

}  // namespace
}  // namespace vsurg::sim
