// A palpation's metrics and score (common/scoring/palpation.h): marks paired with lumps closest
// first, the coverage of the presses, the gates, and the state a moved session goes on from.
#include "common/scoring/palpation.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "common/core/state_archive.h"

namespace vsurg::scoring {
namespace {

// A flat 10 cm square of 1 cm cells (two triangles each, centroids a third of the way in).
PalpableSurface Square() {
  PalpableSurface s;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) {
      s.centroids.push_back(Eigen::Vector3d((i + 1.0 / 3) * 0.01, (j + 1.0 / 3) * 0.01, 0));
      s.centroids.push_back(Eigen::Vector3d((i + 2.0 / 3) * 0.01, (j + 2.0 / 3) * 0.01, 0));
      s.areas.push_back(0.5e-4);
      s.areas.push_back(0.5e-4);
    }
  return s;
}

Lump LumpAt(double x, double y) {
  return {Eigen::Vector3d(x, y, -0.015), 0.005, Eigen::Vector3d(x, y, 0)};
}

TaskSpec Palpate() {
  TaskSpec t;
  t.kind = TaskKind::kPalpate;
  t.target = 0;
  t.tolerance = 0.005;
  t.hold_s = 0;
  t.force_limit = 3;
  t.time_limit = 300;
  t.expert_time = 100;
  return t;
}

// The trial recorder's part of a search that lasted `duration` s and pressed at `peak` N.
TrialMetrics Timed(double duration, double peak = 1) {
  TrialMetrics m;
  m.duration = duration;
  m.peak_force = peak;
  return m;
}

TEST(PalpationScoringTest, MarksArePairedWithLumpsClosestFirstWithinTheMargin) {
  PalpationRecorder r({LumpAt(0.03, 0.03), LumpAt(0.07, 0.07)}, Square(), {});
  r.Add(true, {0.05, 0.05, 0}, 1.0);
  EXPECT_TRUE(r.Mark(1, {0.033, 0.03, 0}));   // 3 mm from the first lump
  EXPECT_TRUE(r.Mark(2, {0.030, 0.037, 0}));  // 7 mm: the first is taken by the nearer mark
  EXPECT_TRUE(r.Mark(3, {0.07, 0.081, 0}));   // 11 mm: beyond radius + margin (10 mm)
  TrialMetrics m = Timed(100);
  r.Complete(m, Palpate());
  EXPECT_EQ(m.lumps, 2);
  EXPECT_EQ(m.lumps_found, 1);
  EXPECT_EQ(m.false_marks, 2);
  EXPECT_NEAR(m.localisation_error, 0.003, 1e-12);
  EXPECT_TRUE(m.completed);
  // Detection (1 − ½·2)/2 = 0: the accuracy part is lost whole, and the explanation says why.
  EXPECT_DOUBLE_EQ(PalpationScoreParts(m, Palpate()).accuracy, 0);
  const std::vector<std::string> why = ExplainPalpation(m, Palpate());
  ASSERT_FALSE(why.empty());
  EXPECT_NE(why[0].find("1 of 2 lump(s) found, 2 false mark(s)"), std::string::npos) << why[0];
}

TEST(PalpationScoringTest, ACleanSearchOfAPadWithoutLumpsScoresFull) {
  PalpationRecorder r({}, Square(), {});
  for (int i = 0; i <= 10; ++i)
    for (int j = 0; j <= 100; ++j) r.Add(true, {i * 0.01, j * 0.001, 0}, 1.0);
  TrialMetrics m = Timed(80);
  r.Complete(m, Palpate());
  EXPECT_EQ(m.lumps, 0);
  EXPECT_EQ(m.false_marks, 0);
  EXPECT_GT(m.coverage, 0.99);
  EXPECT_DOUBLE_EQ(m.mean_force, 1.0);
  EXPECT_DOUBLE_EQ(m.score, 10);
  EXPECT_TRUE(ExplainPalpation(m, Palpate()).empty());
}

// Coverage counts each cell once, only under a press at least press_force firm, within the
// cover radius: one press in the middle of the square covers the centroids within 6 mm.
TEST(PalpationScoringTest, CoverageIsTheAreaUnderFirmPressesCountedOnce) {
  const PalpableSurface square = Square();
  const Eigen::Vector3d centre(0.05, 0.05, 0);
  double expected = 0;
  for (size_t t = 0; t < square.centroids.size(); ++t)
    if ((square.centroids[t] - centre).norm() <= 0.006) expected += square.areas[t];
  PalpationRecorder r({}, square, {});
  r.Add(true, {0.02, 0.02, 0}, 0.1);                     // too light to examine anything
  r.Add(false, {0.08, 0.08, 0}, 2.0);                    // not in contact
  for (int k = 0; k < 5; ++k) r.Add(true, centre, 1.0);  // the same press, counted once
  TrialMetrics m = Timed(10);
  r.Complete(m, Palpate());
  EXPECT_NEAR(m.coverage, expected / 0.01, 1e-12);
  EXPECT_GT(m.coverage, 0);
  EXPECT_NEAR(m.mean_force, (0.1 + 5 * 1.0) / 6, 1e-12);
}

TEST(PalpationScoringTest, TheGatesCapASearchNotFinishedOrTooForceful) {
  PalpationRecorder r({LumpAt(0.03, 0.03)}, Square(), {});
  r.Add(true, {0.03, 0.03, 0}, 1.0);
  r.Mark(1, {0.03, 0.03, 0});
  TrialMetrics late = Timed(300);  // the time limit ran out
  r.Complete(late, Palpate());
  EXPECT_FALSE(late.completed);
  EXPECT_LE(late.score, 5);
  EXPECT_TRUE(late.caps & kCapNotCompleted);
  TrialMetrics hard = Timed(50, 4);
  hard.time_over_force_limit = 0.8;
  r.Complete(hard, Palpate());
  EXPECT_TRUE(hard.completed);
  EXPECT_LE(hard.score, 4);
  TrialMetrics untouched = Timed(50);
  PalpationRecorder(std::vector<Lump>{}, Square(), {}).Complete(untouched, Palpate());
  EXPECT_FALSE(untouched.completed);  // nothing pressed: not a search
}

TEST(PalpationScoringTest, BadInputIsIgnoredAndMarksAreBounded) {
  PalpationRecorder r({LumpAt(0.03, 0.03)}, Square(), {});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.Add(true, {nan, 0, 0}, 1.0);
  r.Add(true, {0.03, 0.03, 0}, nan);
  EXPECT_FALSE(r.Mark(1, {nan, 0, 0}));
  for (int k = 0; k < PalpationRecorder::kMaxMarks; ++k) EXPECT_TRUE(r.Mark(k, {0.09, 0.09, 0}));
  EXPECT_FALSE(r.Mark(99, {0.03, 0.03, 0}));
  TrialMetrics m = Timed(10);
  r.Complete(m, Palpate());
  EXPECT_EQ(m.false_marks, PalpationRecorder::kMaxMarks);
  EXPECT_EQ(m.coverage, 0);
  EXPECT_TRUE(std::isfinite(m.score));
}

TEST(PalpationScoringTest, TheStateReadsBackIntoARecorderOfTheSameSurface) {
  PalpationRecorder r({LumpAt(0.03, 0.03)}, Square(), {});
  r.Add(true, {0.03, 0.03, 0}, 1.0);
  r.Mark(1, {0.031, 0.03, 0});
  StateWriter w;
  w(r);
  const std::string bytes = w.Take();
  PalpationRecorder back({LumpAt(0.03, 0.03)}, Square(), {});
  StateReader reader(bytes);
  reader(back);
  ASSERT_TRUE(reader.done());
  TrialMetrics a = Timed(20), b = Timed(20);
  r.Complete(a, Palpate());
  back.Complete(b, Palpate());
  EXPECT_EQ(a.lumps_found, b.lumps_found);
  EXPECT_EQ(a.coverage, b.coverage);
  EXPECT_EQ(a.score, b.score);
  // A recorder of another surface does not take it.
  PalpableSurface small = Square();
  small.centroids.resize(10);
  small.areas.resize(10);
  PalpationRecorder other({}, small, {});
  StateReader wrong(bytes);
  wrong(other);
  EXPECT_FALSE(wrong.ok());
}

}  // namespace
}  // namespace vsurg::scoring
