#include "common/scoring/evaluation.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace vsurg::scoring {
namespace {

using G = EvaluatorGroup;

Rating Uniform(const std::string& who, G group, double score) {
  Rating r;
  r.evaluator = who;
  r.group = group;
  r.scores.fill(score);
  return r;
}

// Shrout & Fleiss (1979) Table 2: 6 targets × 4 judges. Published: ICC(2,k) = 0.62,
// ICC(3,k) = 0.91 (which equals Cronbach's α with the judges as items).
const std::vector<double> kShroutFleiss = {9, 2, 5, 8, 6,  1, 3, 2, 8, 4, 6, 8,
                                           7, 1, 2, 6, 10, 5, 6, 9, 6, 2, 4, 7};

TEST(EvaluationTest, Icc2kMatchesShroutAndFleiss) {
  EXPECT_NEAR(Icc2k(kShroutFleiss, 6, 4), 0.620050547598989, 1e-12);
}

TEST(EvaluationTest, CronbachAlphaMatchesShroutAndFleissIcc3k) {
  EXPECT_NEAR(CronbachAlpha(kShroutFleiss, 6, 4), 0.9093155423770694, 1e-12);
}

TEST(EvaluationTest, ReliabilityIsUndefinedNotInventedForDegenerateInput) {
  EXPECT_TRUE(std::isnan(Icc2k(std::vector<double>{1, 2, 3}, 1, 3)));       // one target
  EXPECT_TRUE(std::isnan(Icc2k(std::vector<double>(12, 5.0), 4, 3)));       // no variance
  EXPECT_TRUE(std::isnan(CronbachAlpha(std::vector<double>{1, 2}, 1, 2)));  // one case
  EXPECT_TRUE(std::isnan(Icc2k(std::vector<double>{1, 2, 3}, 2, 2)));       // wrong size
}

TEST(EvaluationTest, AbsoluteAgreementPenalisesARaterBiasThatConsistencyIgnores) {
  // Rater 2 scores every target exactly 2 points above rater 1: perfectly consistent, not in
  // absolute agreement.
  const std::vector<double> x = {3, 5, 5, 7, 6, 8, 8, 10};
  EXPECT_NEAR(CronbachAlpha(x, 4, 2), 1.0, 1e-12);
  const double icc = Icc2k(x, 4, 2);
  EXPECT_LT(icc, 0.9);
  EXPECT_GT(icc, 0.0);
}

TEST(EvaluationTest, Eq9WeighsGroupMeansNotRaters) {
  // Twenty interns at 5, ten associates at 7, ten chiefs at 9 (the paper's panel sizes).
  std::vector<Rating> r;
  for (int i = 0; i < 20; ++i) r.push_back(Uniform("a" + std::to_string(i), G::kIntern, 5));
  for (int i = 0; i < 10; ++i) r.push_back(Uniform("b" + std::to_string(i), G::kAssociateChief, 7));
  for (int i = 0; i < 10; ++i) r.push_back(Uniform("c" + std::to_string(i), G::kChief, 9));
  auto rep = Evaluate(r, WeightSet{});
  ASSERT_TRUE(rep.ok()) << rep.error().message;
  const double m = 0.2 * 5 + 0.3 * 7 + 0.5 * 9;  // 7.6, not the per-rater mean 6.5
  for (double v : rep->index_means) EXPECT_NEAR(v, m, 1e-12);
  EXPECT_NEAR(rep->comprehensive, m, 1e-12);  // index weights sum to 1
  EXPECT_FALSE(rep->renormalised);
  EXPECT_EQ(rep->raters, 40);
  EXPECT_EQ(rep->raters_per_group[0], 20);
  // eq. 10: population variance about M_j (not about the plain mean)
  const double s = (20 * (5 - m) * (5 - m) + 10 * (7 - m) * (7 - m) + 10 * (9 - m) * (9 - m)) / 40;
  for (double v : rep->index_variances) EXPECT_NEAR(v, s, 1e-12);
}

TEST(EvaluationTest, Eq11UsesTheIndexWeights) {
  Rating a = Uniform("a", G::kChief, 0);
  for (int j = 0; j < kIndexCount; ++j) a.scores[j] = j + 1;  // 1..9
  auto rep = Evaluate(std::vector<Rating>{a}, WeightSet{});
  ASSERT_TRUE(rep.ok());
  const double n = 0.15 * (1 + 2 + 3 + 4) + 0.10 * (5 + 6 + 7) + 0.05 * (8 + 9);
  EXPECT_NEAR(rep->comprehensive, n, 1e-12);
  for (double v : rep->index_variances) EXPECT_EQ(v, 0.0);
  EXPECT_TRUE(std::isnan(rep->cronbach_alpha));  // one rater: no agreement to measure
}

TEST(EvaluationTest, AnAbsentGroupIsRenormalisedAndReported) {
  std::vector<Rating> r = {Uniform("a", G::kIntern, 4), Uniform("c", G::kChief, 8)};
  auto rep = Evaluate(r, WeightSet{});
  ASSERT_TRUE(rep.ok());
  EXPECT_TRUE(rep->renormalised);
  ASSERT_EQ(rep->absent_groups.size(), 1u);
  EXPECT_EQ(rep->absent_groups[0], "associate_chief");
  EXPECT_NEAR(rep->group_weights_used[0], 0.2 / 0.7, 1e-12);
  EXPECT_EQ(rep->group_weights_used[1], 0.0);
  EXPECT_NEAR(rep->index_means[0], (0.2 * 4 + 0.5 * 8) / 0.7, 1e-12);
}

TEST(EvaluationTest, CustomWeightsAreUsedAndRecorded) {
  WeightSet w;
  w.name = "equal";
  w.group = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  w.index.fill(1.0 / 9);
  std::vector<Rating> r = {Uniform("a", G::kIntern, 3), Uniform("b", G::kAssociateChief, 6),
                           Uniform("c", G::kChief, 9)};
  auto rep = Evaluate(r, w);
  ASSERT_TRUE(rep.ok());
  EXPECT_NEAR(rep->comprehensive, 6.0, 1e-12);
  EXPECT_EQ(rep->weights.name, "equal");
}

TEST(EvaluationTest, BadInputIsRejectedNamingTheField) {
  Rating bad = Uniform("a", G::kChief, 5);
  bad.scores[3] = 10.5;
  auto r1 = Evaluate(std::vector<Rating>{bad}, WeightSet{});
  ASSERT_FALSE(r1.ok());
  EXPECT_EQ(r1.error().field, "ratings[0].scores[3]");
  bad.scores[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(Evaluate(std::vector<Rating>{bad}, WeightSet{}).ok());
  bad.scores[3] = -0.1;
  EXPECT_FALSE(Evaluate(std::vector<Rating>{bad}, WeightSet{}).ok());

  auto twice = Evaluate(
      std::vector<Rating>{Uniform("a", G::kChief, 5), Uniform("a", G::kIntern, 5)}, WeightSet{});
  ASSERT_FALSE(twice.ok());
  EXPECT_EQ(twice.error().field, "ratings[1].evaluator");

  EXPECT_FALSE(Evaluate(std::vector<Rating>{}, WeightSet{}).ok());
  WeightSet w;
  w.index[0] = 0.2;  // sums to 1.05
  auto r2 = Evaluate(std::vector<Rating>{Uniform("a", G::kChief, 5)}, w);
  ASSERT_FALSE(r2.ok());
  EXPECT_EQ(r2.error().field, "index_weights");
  w = WeightSet{};
  w.group = {0.5, 0.5, 0.0};
  auto r3 = Evaluate(std::vector<Rating>{Uniform("a", G::kChief, 5)}, w);
  EXPECT_FALSE(r3.ok());  // the only group present has weight 0
}

TEST(EvaluationTest, GroupsParseByTheirStoredNamesOnly) {
  EXPECT_EQ(ParseGroup("intern"), G::kIntern);
  EXPECT_EQ(ParseGroup("associate_chief"), G::kAssociateChief);
  EXPECT_EQ(ParseGroup("chief"), G::kChief);
  EXPECT_FALSE(ParseGroup("Chief").has_value());
  EXPECT_FALSE(ParseGroup("").has_value());
  for (int g = 0; g < kGroupCount; ++g)
    EXPECT_EQ(ParseGroup(GroupName(static_cast<G>(g))), static_cast<G>(g));
}

TEST(EvaluationTest, CompareGivesIccPerIndexOverCommonRaters) {
  // Three simulator models rated by the same three raters; index 0 in close agreement,
  // index 1 where the raters disagree on the ordering.
  auto rating = [](const std::string& who, G g, double i0, double i1) {
    Rating r = Uniform(who, g, 5);
    r.scores[0] = i0;
    r.scores[1] = i1;
    return r;
  };
  std::vector<SubjectRatings> s = {
      {"coil",
       {rating("x", G::kIntern, 9, 2), rating("y", G::kChief, 9, 8), rating("z", G::kChief, 8, 5)}},
      {"msm",
       {rating("x", G::kIntern, 6, 8), rating("y", G::kChief, 6, 2), rating("z", G::kChief, 7, 5)}},
      {"fem",
       {rating("x", G::kIntern, 3, 5), rating("y", G::kChief, 2, 5), rating("z", G::kChief, 3, 9),
        rating("w", G::kChief, 1, 1)}},
  };
  auto c = Compare(s, WeightSet{});
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->common_raters, 3);  // w rated only one model
  ASSERT_EQ(c->subjects.size(), 3u);
  EXPECT_EQ(c->subjects[2].raters, 4);
  EXPECT_GT(c->icc2k_per_index[0], 0.95);
  EXPECT_FALSE(c->icc2k_per_index[1] >= 0.3);      // low, or undefined (NaN) as here
  EXPECT_TRUE(std::isnan(c->icc2k_per_index[2]));  // every subject scored 5 by everyone
}

TEST(EvaluationTest, TrainingEffectAveragesEvaluatorsPerTraineeThenGroups) {
  std::vector<TrainingScore> s = {
      {"t1", "virtual-40", 0, "e1", 4},  {"t1", "virtual-40", 0, "e2", 6},   // t1: 5
      {"t2", "virtual-40", 0, "e1", 7},  {"t2", "virtual-40", 0, "e2", 7},   // t2: 7
      {"t1", "virtual-40", 40, "e1", 9}, {"t2", "virtual-40", 40, "e1", 8},  //
      {"t3", "real-40", 0, "e1", 5},
  };
  auto cells = TrainingEffect(s);
  ASSERT_TRUE(cells.ok()) << cells.error().message;
  ASSERT_EQ(cells->size(), 3u);
  const TrainingCell& c0 = (*cells)[1];  // sorted: real-40 first
  EXPECT_EQ(c0.trainee_group, "virtual-40");
  EXPECT_EQ(c0.moment_min, 0);
  EXPECT_EQ(c0.trainees, 2);
  EXPECT_NEAR(c0.mean, 6.0, 1e-12);
  EXPECT_NEAR(c0.variance, 1.0, 1e-12);
  EXPECT_NEAR((*cells)[2].mean, 8.5, 1e-12);
  s.push_back({"t3", "real-40", 0, "e1", 6});  // the same evaluator twice
  EXPECT_FALSE(TrainingEffect(s).ok());
}

}  // namespace
}  // namespace vsurg::scoring
