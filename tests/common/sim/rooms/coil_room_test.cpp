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

}  // namespace
}  // namespace vsurg::sim
