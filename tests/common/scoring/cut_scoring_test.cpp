// Pattern cutting's metrics (common/scoring/cut.h): the distance to a line and a circle, the
// deviation and the band, the coverage, the lifts and the completion.
#include "common/scoring/cut.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace vsurg::scoring {
namespace {

CutPattern Line() {
  CutPattern p;
  p.ax = -0.02, p.bx = 0.02, p.band = 0.002;
  return p;
}

TEST(CutScoringTest, DistancesToALineAndACircle) {
  CutPattern circle;
  circle.kind = CutPattern::Kind::kCircle;
  circle.radius = 0.01;
  double u = 0;
  EXPECT_NEAR(circle.Distance(0, 0.013, &u), 0.003, 1e-12);
  EXPECT_NEAR(u, 0.25, 1e-12);
  EXPECT_NEAR(circle.Length(), 2 * std::numbers::pi * 0.01, 1e-12);
  EXPECT_NEAR(Line().Distance(0.03, 0.001, &u), std::hypot(0.01, 0.001), 1e-12);
  EXPECT_NEAR(u, 1.0, 1e-12);
}

TEST(CutScoringTest, ACutOnTheLineCoversItAndOneBesideItIsOutside) {
  CutTask task;
  task.pattern = Line();
  task.expert_time = 5;
  CutRecorder on(task.pattern);
  for (int i = 0; i < 100; ++i) on.AddSample(i * 0.05, -0.02 + i * 4e-4, 0, true, 2.0, 3.0);
  on.AddCut(-0.02, 0.0005, 0.02, 0.0005);
  const CutMetrics m = on.Complete(task);
  EXPECT_TRUE(m.completed);
  EXPECT_NEAR(m.deviation_rms, 0.0005, 1e-9);
  EXPECT_NEAR(m.coverage, 1.0, 0.01);
  EXPECT_EQ(m.outside_length, 0.0);
  EXPECT_EQ(m.lifts, 0);
  EXPECT_GT(m.score, 8);

  CutRecorder off(task.pattern);
  off.AddSample(0, -0.02, 0.004, true, 2.0, 3.0);
  off.AddSample(1, -0.02, 0.004, false, 2.0, 3.0);
  off.AddSample(2, -0.02, 0.004, true, 4.0, 3.0);
  off.AddCut(-0.02, 0.004, 0.0, 0.004);  // 4 mm off the line, half of it
  const CutMetrics b = off.Complete(task);
  EXPECT_FALSE(b.completed);
  EXPECT_NEAR(b.outside_length, 0.02, 1e-9);
  EXPECT_EQ(b.coverage, 0.0);
  EXPECT_EQ(b.lifts, 1);
  EXPECT_NEAR(b.time_over_limit, 1.0, 1e-12);
  EXPECT_LT(b.score, m.score - 4);
  EXPECT_FALSE(ExplainCut(b, task).empty());
}

TEST(CutScoringTest, ACircleIsCompleteOnlyWhenThePieceComesFree) {
  CutTask task;
  task.pattern.kind = CutPattern::Kind::kCircle;
  task.pattern.radius = 0.01;
  CutRecorder r(task.pattern);
  const int n = 400;
  for (int i = 0; i < n; ++i) {
    const double a0 = 2 * std::numbers::pi * i / n, a1 = 2 * std::numbers::pi * (i + 1) / n;
    r.AddSample(i * 0.01, 0.01 * std::cos(a0), 0.01 * std::sin(a0), true, 2, 3);
    r.AddCut(0.01 * std::cos(a0), 0.01 * std::sin(a0), 0.01 * std::cos(a1), 0.01 * std::sin(a1));
  }
  EXPECT_FALSE(r.Complete(task).completed);
  r.PieceFreed(4.0);
  const CutMetrics m = r.Complete(task);
  EXPECT_TRUE(m.completed);
  EXPECT_NEAR(m.completion_time, 4.0, 1e-9);
  EXPECT_LT(m.deviation_max, 0.01 * (1 - std::cos(std::numbers::pi / n)) + 1e-9);
}

TEST(CutScoringTest, NotFiniteSamplesAreIgnored) {
  CutRecorder r(Line());
  r.AddSample(NAN, 0, 0, true, 1, 3);
  r.AddCut(NAN, 0, 0, 0);
  const CutMetrics m = r.Complete(CutTask{});
  EXPECT_EQ(m.cut_length, 0.0);
  EXPECT_TRUE(std::isfinite(m.score));
}

}  // namespace
}  // namespace vsurg::scoring
