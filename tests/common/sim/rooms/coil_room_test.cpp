// The coil room (common/sim/rooms/coil_room.h): the coil-spring model twisting the forearm.
#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, ScriptedTraineesOnTheArmGiveTheExpectedMetrics) {
  double peak = 0;
  const scoring::TrialMetrics good = Replay("arm-torsion", TraineeStyle::kGood, &peak);
  ASSERT_TRUE(good.completed);
  // Approach 0.4 s + pause 0.5 s + 2 s twist (enters the 5° band about 1.6 s in) + 2 s hold.
  EXPECT_NEAR(good.completion_time, 0.4 + 0.5 + 1.5 + 2.0, 0.3);
  EXPECT_LT(good.task_error, 5 * M_PI / 180);
  EXPECT_LE(peak, 3.3 + 1e-9);
  EXPECT_LT(good.peak_force, 3.0);  // under the task's force limit
  EXPECT_EQ(good.overload_events, 0);
  EXPECT_GE(good.score, 8.0);
  const scoring::TrialMetrics hesitant = Replay("arm-torsion", TraineeStyle::kHesitant);
  ASSERT_TRUE(hesitant.completed);
  EXPECT_GT(hesitant.completion_time, good.completion_time + 3.0);
  EXPECT_LT(hesitant.score, good.score);
  EXPECT_GT(hesitant.path_length, 0.9 * good.path_length);
  const scoring::TrialMetrics rough = Replay("arm-torsion", TraineeStyle::kRough, &peak);
  EXPECT_GT(rough.time_over_force_limit, 0.5);  // overshooting a limb twist loads it hard
  EXPECT_TRUE(rough.caps & scoring::kCapForceLimit);
  EXPECT_LE(rough.score, 4.0);
  // Jerk is read on a 10 ms grid (trial_metrics.cpp: robust to the station clock's jitter), which
  // sees hand motion up to 50 Hz: the rough trainee's is 80× the good one's (its content above
  // 50 Hz counted for more on the former 1 ms differences, with the jitter).
  EXPECT_GT(rough.rms_jerk, 50 * good.rms_jerk);
  EXPECT_LE(peak, 3.3 + 1e-9);  // the device limit holds whatever the trainee does
}

// While the hand grasps, the haptic path answers from the twist's own law and never reads the
// surface: each update goes to the view (its frames show the arm turning, as the twist's numbers)
// and the surface the path would touch stays the one from before the grasp, consistent with its
// bounding boxes; the release publishes the released surface again, back at rest.
TEST(RoomTest, WhileTheArmIsGraspedOnlyItsViewMovesAndTheReleaseRestoresTheSurface) {
  auto scene = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok());
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  auto sim = Simulation::Create(*scene, {false});
  ASSERT_TRUE(sim.ok());
  Simulation& s = **sim;
  VisualFrame frame;
  size_t next = 0;
  uint64_t updates = 0, surfaces = 0;
  bool grasped = false, released = false;
  for (; next < samples->size() && !released; ++next) {
    const haptics::ForceCommand cmd = s.OnStylus((*samples)[next]);
    s.StepDeformation();
    if (cmd.grasping && !grasped) {
      grasped = true;
      updates = s.deformation_updates();
      surfaces = s.surface_updates();
    }
    released = grasped && !cmd.grasping;
  }
  ASSERT_TRUE(grasped && released);
  // The grasp's updates (before the release's own) reached the view only.
  EXPECT_GT(s.deformation_updates(), updates + 100);
  EXPECT_EQ(s.surface_updates(), surfaces + 1) << "only the release's";
  // The view after the release: the arm back at rest, described as the limb's twist at zero.
  ASSERT_TRUE(s.TakeVisualFrame(frame));
  ASSERT_TRUE(frame.twist.has_value());
  EXPECT_EQ(frame.twist->torque, 0.0);
  std::vector<int32_t> indices;
  std::vector<geometry::Vec3> positions;
  s.ShownSurface(indices, positions);
  EXPECT_TRUE(indices.empty()) << indices.size() << " vertices away from rest";
}

// A station that remakes the limb's twist from its numbers (frames taken with the limb's key) is
// sent the shape alone, and no vertex is made or compared for it while the hand grasps. The
// monitors still read the twisted arm (ShownSurface, as a station sent vertices sees it), and a
// frame that needs vertices later (the release) is made against the twist the station was shown.
TEST(RoomTest, FramesAsTheTwistMakeNoVerticesYetTheArmIsShownTwisted) {
  auto scene = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok());
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  auto twist_sim = Simulation::Create(*scene, {false});
  auto vertex_sim = Simulation::Create(*scene, {false});
  ASSERT_TRUE(twist_sim.ok() && vertex_sim.ok());
  Simulation &a = **twist_sim, &b = **vertex_sim;
  VisualFrame fa, fb;
  uint64_t key = 0;
  int shape_only = 0, compared = 0;
  std::vector<int32_t> ia, ib;
  std::vector<geometry::Vec3> pa, pb;
  // Every vertex from a ShownSurface (the others at rest).
  const auto whole = [&](const std::vector<int32_t>& idx, const std::vector<geometry::Vec3>& pos) {
    std::vector<geometry::Vec3> all = b.rest_mesh().positions;
    for (size_t k = 0; k < idx.size(); ++k) all[idx[k]] = pos[k];
    return all;
  };
  bool grasped = false;
  for (size_t k = 0; k < samples->size(); ++k) {
    const bool grasping = a.OnStylus((*samples)[k]).grasping;
    b.OnStylus((*samples)[k]);
    a.StepDeformation(), b.StepDeformation();
    grasped = grasped || grasping;
    if (k % 16 != 0) continue;  // a frame every 16 ms
    const bool took = a.TakeVisualFrame(fa, key);
    ASSERT_EQ(took, b.TakeVisualFrame(fb));
    if (!took) continue;
    if (!key && fb.twist) key = fb.twist->key;
    if (grasping && fa.twist && fa.twist->key == key) {
      EXPECT_TRUE(fa.indices.empty()) << "a shape-only frame carried vertices";
      EXPECT_EQ(fa.twist->torque, fb.twist->torque);
      ++shape_only;
    }
    if (grasping && shape_only > 0 && k % 256 == 0) {  // the monitors' view of both
      a.ShownSurface(ia, pa);
      b.ShownSurface(ib, pb);
      const std::vector<geometry::Vec3> shown_a = whole(ia, pa), shown_b = whole(ib, pb);
      double worst = 0;
      for (size_t v = 0; v < shown_a.size(); ++v)
        worst = std::max(worst, (shown_a[v] - shown_b[v]).norm());
      EXPECT_LT(worst, 1.01e-6) << "the vertex frames' own 1 µm";
      compared += !ib.empty();  // the arm turned
    }
  }
  ASSERT_TRUE(grasped);
  EXPECT_GT(shape_only, 100);
  EXPECT_GT(compared, 3);
  // Released: the station sent vertices is told which went back to rest; so would be the one
  // that was sent the twist, had its frame needed vertices (taken without the key).
  a.TakeVisualFrame(fa, 0);
  b.TakeVisualFrame(fb);
  EXPECT_EQ(a.LastFramePositions(), b.LastFramePositions());
  a.ShownSurface(ia, pa);
  EXPECT_TRUE(ia.empty()) << ia.size() << " vertices away from rest after the release";
}

}  // namespace
}  // namespace vsurg::sim
