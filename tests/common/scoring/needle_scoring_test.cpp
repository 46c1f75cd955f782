// A needle insertion's metrics and score (common/scoring/needle.h).
#include "common/scoring/needle.h"

#include <gtest/gtest.h>

#include <limits>

#include "common/scoring/proficiency.h"

namespace vsurg::scoring {
namespace {

TaskSpec Insert() {
  TaskSpec t;
  t.kind = TaskKind::kInsert;
  t.target = 0;
  t.tolerance = 0.002;
  t.time_limit = 90;
  t.expert_time = 12;
  t.force_limit = 3;
  return t;
}

NeedleSample In(double depth_error, bool in_target = true) {
  return {true, in_target, 0.01, depth_error, 0.0005, 4};
}

TrialMetrics NeedleTrial(double duration) {
  TrialMetrics m;
  m.duration = duration;
  m.peak_force = 1.5;
  return m;
}

TEST(NeedleScoringTest, AConfirmedPlacementIsScoredOnItsDepthAimCareAndTime) {
  NeedleRecorder r;
  r.Add(In(0.004, false));
  r.Add(In(0.001));
  ASSERT_TRUE(r.Confirm(10, In(0.001)));
  r.Add(In(0.009));  // after the confirmation: not what was placed
  TrialMetrics m = NeedleTrial(12);
  r.Complete(m, Insert(), 4, 0);
  EXPECT_TRUE(m.completed);
  EXPECT_DOUBLE_EQ(m.completion_time, 10);
  EXPECT_DOUBLE_EQ(m.depth_error, 0.001);
  EXPECT_DOUBLE_EQ(m.path_deviation, 0.0005);
  EXPECT_EQ(m.extra_punctures, 0);
  const ScoreParts p = NeedleScoreParts(m, Insert());
  EXPECT_NEAR(p.accuracy, 1 - 0.001 / 0.004 - 0.0005 / 0.008, 1e-12);
  EXPECT_NEAR(p.smoothness, 1 - 0.01 / kNeedleStrainLimit, 1e-12);  // tissue care
  EXPECT_DOUBLE_EQ(p.efficiency, 1.0);                              // under the expert's time
  EXPECT_EQ(m.caps, 0u);
}

TEST(NeedleScoringTest, AConfirmationOutsideTheTargetIsNotAPlacement) {
  NeedleRecorder r;
  EXPECT_FALSE(r.Confirm(5, In(0.006, false)));
  EXPECT_EQ(r.wrong_confirmations(), 1);
  r.Add(In(0.003, false));
  TrialMetrics m = NeedleTrial(90);
  r.Complete(m, Insert(), 3, 0);
  EXPECT_FALSE(m.completed);
  EXPECT_DOUBLE_EQ(m.depth_error, 0.003);  // the closest the tip came
  EXPECT_TRUE(m.caps & kCapNotCompleted);
  EXPECT_LE(m.score, 5.0);
}

TEST(NeedleScoringTest, ABackWallBreachCapsAtThreeAndExtraPuncturesCostCare) {
  NeedleRecorder r;
  r.Add(In(0.0));
  ASSERT_TRUE(r.Confirm(3, In(0.0)));
  TrialMetrics m = NeedleTrial(4);
  r.Complete(m, Insert(), 9, 1);
  EXPECT_EQ(m.extra_punctures, 5);
  EXPECT_TRUE(m.caps & kCapBackWall);
  EXPECT_LE(m.score, 3.0);
  EXPECT_DOUBLE_EQ(NeedleScoreParts(m, Insert()).smoothness, 0.0);  // 5 × ¼ beyond the strain's
  const std::vector<std::string> why = ExplainNeedle(m, Insert());
  ASSERT_GE(why.size(), 2u);
  EXPECT_NE(why[0].find("Placed 0.0 mm"), std::string::npos) << why[0];
  EXPECT_NE(why[1].find("back wall"), std::string::npos) << why[1];
}

TEST(NeedleScoringTest, ANeedleNeverInTheTissueEarnsNoPlacementAndNoCare) {
  NeedleRecorder r;
  TrialMetrics m = NeedleTrial(90);
  r.Complete(m, Insert(), 0, 0);
  EXPECT_EQ(NeedleScoreParts(m, Insert()).accuracy, 0.0);
  EXPECT_EQ(NeedleScoreParts(m, Insert()).smoothness, 0.0);
  // A target on the needle's depth error cannot be met by never placing one.
  const MetricDef* depth = FindMetric("depth_error_m");
  ASSERT_NE(depth, nullptr);
  EXPECT_EQ(MetricValue(m, *depth), std::numeric_limits<double>::infinity());
  m.punctures = 4, m.depth_error = 0.001;
  EXPECT_DOUBLE_EQ(MetricValue(m, *depth), 0.001);
}

}  // namespace
}  // namespace vsurg::scoring
