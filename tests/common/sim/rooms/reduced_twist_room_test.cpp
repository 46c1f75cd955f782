// The reduced twist room (common/sim/rooms/reduced_twist_room.h): the limb twisted by its
// precomputed twist field.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, TheReducedArmIsTwistedToTheTargetAndCachesItsField) {
  namespace fs = std::filesystem;
  const test::TempDir dir("arm_cache");
  setenv("VSURG_CACHE_DIR", dir.string().c_str(), 1);
  double peak = 0;
  const scoring::TrialMetrics good = Replay("arm-torsion-reduced", TraineeStyle::kGood, &peak);
  unsetenv("VSURG_CACHE_DIR");
  EXPECT_TRUE(fs::exists(dir / "arm-torsion-reduced-twist.vrm"));
  ASSERT_TRUE(good.completed);
  EXPECT_LT(good.task_error, 5 * M_PI / 180);
  EXPECT_LE(peak, 3.3 + 1e-9);
  EXPECT_GE(good.score, 8.0);
  EXPECT_EQ(good.overload_events, 0);
}

// The arm with a hyperelastic law: its table of load levels is built and cached, the good trainee
// turns it to the target as on the linear field, and the exponential law's grasp is stiffer than
// the neo-Hookean one's (the same small-strain modulus, b = 5: 9% at the peak on this coarse mesh).
TEST(RoomTest, AHyperelasticArmIsTwistedByItsTableAndTheExponentialLawStiffens) {
  namespace fs = std::filesystem;
  const test::TempDir dir("arm_table_cache");
  setenv("VSURG_CACHE_DIR", dir.string().c_str(), 1);
  auto arm = LoadSceneByName("arm-torsion-reduced");
  ASSERT_TRUE(arm.ok());
  arm->region.reduced.fem_rings = 2;  // a coarse FEM: a few seconds of Newton solves
  arm->region.reduced.levels = 3;
  // A 2-ring FEM is about 14% stiffer than the scene's 4 rings: the grasp at 45° needs more than
  // the task's 3 N of device force.
  arm->task.force_limit = 6;
  auto run = [&](Scene::Law law, double b, double* peak) {
    Scene s = *arm;
    s.law = law;
    s.stiffening = b;
    auto samples = ScriptedTrainee(s, TraineeStyle::kGood);
    EXPECT_TRUE(samples.ok());
    auto sim = Simulation::Create(s, {false});
    EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
    *peak = 0;
    (*sim)->Replay(*samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
      *peak = std::max(*peak, std::abs(c.torque));
    });
    return (*sim)->Metrics();
  };
  double neo_torque = 0, expo_torque = 0;
  const scoring::TrialMetrics neo = run(Scene::Law::kNeoHookean, 0, &neo_torque);
  const scoring::TrialMetrics expo = run(Scene::Law::kExponential, 5, &expo_torque);
  unsetenv("VSURG_CACHE_DIR");
  EXPECT_TRUE(fs::exists(dir / "arm-torsion-reduced-twist-table.vrm"));
  for (const scoring::TrialMetrics* m : {&neo, &expo}) {
    ASSERT_TRUE(m->completed);
    EXPECT_LT(m->task_error, 5 * M_PI / 180);
    EXPECT_EQ(m->overload_events, 0);
  }
  EXPECT_GT(neo_torque, 1.0);  // N·m: the forearm held at 45°
  EXPECT_GT(expo_torque, 1.01 * neo_torque);
  EXPECT_LT(expo_torque, 1.2 * neo_torque);
}

// A relaxing arm ("tissue.relaxation"): while the good trainee holds the wrist at 45° for its 2 s
// the torque it feels falls towards g∞ of the elastic one (e^{−2/0.5} of the rest is left), while
// the elastic arm's holds; the arm keeps its shape (the grasp holds the twist), so the task
// completes alike. A twist again later starts from a history that has relaxed back.
TEST(RoomTest, ARelaxingArmsTorqueFallsWhileTheTwistIsHeld) {
  const test::TempDir dir("arm_relax_cache");
  setenv("VSURG_CACHE_DIR", dir.string().c_str(), 1);
  auto arm = LoadSceneByName("arm-torsion-reduced");
  ASSERT_TRUE(arm.ok());
  auto run = [&](bool relaxing, std::vector<double>* torque) {
    Scene s = *arm;
    if (relaxing) s.relaxation = {{0.4, 0.5}};
    auto samples = ScriptedTrainee(s, TraineeStyle::kGood);
    EXPECT_TRUE(samples.ok());
    auto sim = Simulation::Create(s, {false});
    EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
    (*sim)->Replay(*samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
      if (c.grasping) torque->push_back(std::abs(c.torque));
    });
    return (*sim)->Metrics();
  };
  std::vector<double> elastic, relaxing;
  const scoring::TrialMetrics a = run(false, &elastic), b = run(true, &relaxing);
  unsetenv("VSURG_CACHE_DIR");
  ASSERT_TRUE(a.completed && b.completed);
  EXPECT_NEAR(b.task_error, a.task_error, 1e-9);  // the same twist held: the same shape
  ASSERT_EQ(elastic.size(), relaxing.size());
  ASSERT_GT(elastic.size(), 2000u);  // the turn and the 2 s hold
  const double e_peak = *std::max_element(elastic.begin(), elastic.end());
  const double r_peak = *std::max_element(relaxing.begin(), relaxing.end());
  // The hold: the samples where the elastic arm is within 5% of its peak (the trainee then turns
  // back before letting go). Held, the relaxing arm's torque falls to about 0.6 of the elastic.
  size_t first = 0, last = 0;
  for (size_t i = 0; i < elastic.size(); ++i) {
    if (elastic[i] < 0.95 * e_peak) continue;
    if (first == 0) first = i;
    last = i;
  }
  EXPECT_GT(last - first, 1500u) << "a hold of at least 1.5 s";
  EXPECT_LT(relaxing[last], 0.7 * elastic[last]);
  EXPECT_GT(relaxing[last], 0.55 * elastic[last]);
  EXPECT_LT(relaxing[last], relaxing[first]);
  EXPECT_LT(r_peak, e_peak);  // already relaxing during the turn
}

}  // namespace
}  // namespace vsurg::sim
