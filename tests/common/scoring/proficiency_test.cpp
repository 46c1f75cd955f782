// Proficiency-based progression, expert benchmarks and the CUSUM learning curve
// (common/scoring/proficiency.h): the rules on hand-made trials, the benchmarks against R's
// quantile type 7 and the sample SD, and the CUSUM against the binomial log-likelihood ratio and
// Wald's error bounds by simulation.
#include "common/scoring/proficiency.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace vsurg::scoring {
namespace {

TrialMetrics Trial(double time_s, double peak_n, double score, bool completed = true) {
  TrialMetrics m;
  m.completed = completed;
  m.completion_time = completed ? time_s : 0;
  m.peak_force = peak_n;
  m.score = score;
  return m;
}

const std::vector<Target> kTargets = {
    {"completion_time_s", 6}, {"peak_force_n", 2.5}, {"score", 8}};

TEST(ProficiencyTest, AnAttemptPassesOnlyWhenEveryTargetIsMet) {
  EXPECT_TRUE(CheckAttempt(Trial(5, 2.0, 9), kTargets).passed);
  EXPECT_TRUE(CheckAttempt(Trial(6, 2.5, 8), kTargets).passed);  // on the target is met
  // Non-compensatory: a very fast, high-scoring trial with one force peak too many fails.
  const AttemptCheck c = CheckAttempt(Trial(2, 2.6, 10), kTargets);
  EXPECT_FALSE(c.passed);
  ASSERT_EQ(c.checks.size(), 3u);
  EXPECT_TRUE(c.checks[0].met);
  EXPECT_FALSE(c.checks[1].met);
  EXPECT_DOUBLE_EQ(c.checks[1].value, 2.6);
  EXPECT_DOUBLE_EQ(c.checks[1].target, 2.5);
  // A trial never completed has no completion time: it fails a time target.
  EXPECT_FALSE(CheckAttempt(Trial(0, 1, 9, false), kTargets).checks[0].met);
  EXPECT_TRUE(CheckAttempt(Trial(0, 1, 9), {}).passed);  // no target: nothing to miss
  EXPECT_FALSE(CheckAttempt(Trial(1, 1, 9), {{"speed", 1}}).passed);
  EXPECT_EQ(ValidateTargets({{"score", 8}, {"speed", 1}}).error().field, "targets[1]");
  EXPECT_EQ(ValidateTargets({{"score", NAN}}).error().field, "targets[0]");
  EXPECT_TRUE(ValidateTargets(kTargets).ok());
}

// An exercise that must be passed unguided names guided_share ≤ 0: a trial an instructor's hand
// weighed in on fails it however well it went, and the same trial alone passes.
TEST(ProficiencyTest, AGuidedShareTargetOfZeroAsksForTheExercisePassedUnguided) {
  std::vector<Target> unguided = kTargets;
  unguided.push_back({"guided_share", 0});
  ASSERT_TRUE(ValidateTargets(unguided).ok());
  TrialMetrics alone = Trial(5, 2.0, 9), guided = alone;
  guided.guided_share = 0.35;
  guided.guided_alpha = 0.5;
  EXPECT_TRUE(CheckAttempt(alone, unguided).passed);
  const AttemptCheck c = CheckAttempt(guided, unguided);
  EXPECT_FALSE(c.passed);
  ASSERT_EQ(c.checks.size(), 4u);
  EXPECT_EQ(c.checks[3].metric, "guided_share");
  EXPECT_DOUBLE_EQ(c.checks[3].value, 0.35);
  EXPECT_FALSE(c.checks[3].met);
  EXPECT_TRUE(CheckAttempt(guided, kTargets).passed);  // without the target, guidance is allowed
  // Two guided trials do not make a streak towards proficiency; the unguided ones after them do.
  std::vector<Attempt> a;
  for (const TrialMetrics* m : {&guided, &guided, &alone, &alone})
    a.push_back({static_cast<int64_t>(a.size()) * 60'000'000, *m});
  EXPECT_EQ(*EvaluateProgress(a, unguided, {2, 0}, 0).proficient_at, 4);
  EXPECT_EQ(*EvaluateProgress(a, kTargets, {2, 0}, 0).proficient_at, 2);
}
TEST(ProficiencyTest, ProficiencyIsTheFirstStreakOfConsecutivePasses) {
  const int64_t day = 86'400'000'000;
  std::vector<Attempt> a;
  // pass, fail, pass, pass (proficient at 4), fail, pass: the later fail does not undo it.
  for (bool pass : {true, false, true, true, false, true})
    a.push_back({day * 10 + static_cast<int64_t>(a.size()) * 60'000'000,
                 pass ? Trial(5, 2, 9) : Trial(9, 2, 6)});
  const Progress p = EvaluateProgress(a, kTargets, {2, 0}, day * 10 + 3'600'000'000);
  EXPECT_EQ(p.attempts, 6);
  EXPECT_EQ(p.passes, 4);
  EXPECT_EQ(p.streak, 1);
  ASSERT_TRUE(p.proficient_at.has_value());
  EXPECT_EQ(*p.proficient_at, 4);
  EXPECT_FALSE(EvaluateProgress(a, kTargets, {3, 0}, 0).proficient_at.has_value());
  EXPECT_EQ(*EvaluateProgress(a, kTargets, {1, 0}, 0).proficient_at, 1);
  EXPECT_FALSE(EvaluateProgress({}, kTargets, {2, 0}, 0).proficient_at.has_value());
}

TEST(ProficiencyTest, AttemptsPerDayCountTheDayInTheSitesZone) {
  const int64_t midnight = 86'400'000'000LL * 20000;  // 2024-10-04 00:00 UTC
  const int64_t hour = 3'600'000'000;
  const std::vector<Attempt> a = {
      {midnight - hour / 2, Trial(5, 2, 9)},   // 23:30 UTC the day before
      {midnight + hour / 2, Trial(5, 2, 9)}};  // 00:30 UTC
  const ProgressionRule rule{2, 2};
  const Progress utc = EvaluateProgress(a, kTargets, rule, midnight + hour);
  EXPECT_EQ(utc.attempts_today, 1);
  EXPECT_TRUE(utc.may_attempt);
  // Two hours west of UTC both were on the same local day (21:30 and 22:30), which is full.
  const Progress west = EvaluateProgress(a, kTargets, rule, midnight + hour, -2 * 3600);
  EXPECT_EQ(west.attempts_today, 2);
  EXPECT_FALSE(west.may_attempt);
  // Before the epoch the days still divide at midnight.
  EXPECT_EQ(EvaluateProgress({{-hour / 2, Trial(5, 2, 9)}}, kTargets, rule, -1).attempts_today, 1);
  EXPECT_EQ(EvaluateProgress({{-hour / 2, Trial(5, 2, 9)}}, kTargets, rule, 1).attempts_today, 0);
}

TEST(ProficiencyTest, ExpertBenchmarksMatchTheSampleSdAndRsQuantileType7) {
  const std::vector<double> times = {10, 12, 14, 16};  // s; mean 13, sample SD √(20/3)
  EXPECT_NEAR(*ExpertBenchmark(times, Better::kLower, BenchmarkMode::kMeanSd),
              13 + std::sqrt(20.0 / 3), 1e-12);
  EXPECT_NEAR(*ExpertBenchmark(times, Better::kHigher, BenchmarkMode::kMeanSd, 2),
              13 - 2 * std::sqrt(20.0 / 3), 1e-12);
  EXPECT_DOUBLE_EQ(*ExpertBenchmark(times, Better::kLower, BenchmarkMode::kMeanSd, 0), 13);
  // quantile(c(10, 12, 14, 16), c(0.25, 0.75)) in R: 11.5, 14.5 (order does not matter).
  const std::vector<double> shuffled = {14, 10, 16, 12};
  EXPECT_DOUBLE_EQ(*ExpertBenchmark(shuffled, Better::kLower, BenchmarkMode::kBestQuartile), 11.5);
  EXPECT_DOUBLE_EQ(*ExpertBenchmark(shuffled, Better::kHigher, BenchmarkMode::kBestQuartile), 14.5);
  const std::vector<double> one = {5}, bad = {5, NAN};
  EXPECT_EQ(ExpertBenchmark(one, Better::kLower, BenchmarkMode::kMeanSd).error().field, "experts");
  EXPECT_EQ(ExpertBenchmark(bad, Better::kLower, BenchmarkMode::kBestQuartile).error().field,
            "experts");
  EXPECT_EQ(ExpertBenchmark(times, Better::kLower, BenchmarkMode::kMeanSd, -1).error().field, "k");
}

TEST(CusumTest, TheCurveIsTheBinomialLogLikelihoodRatioScaled) {
  const CusumParams p{0.1, 0.3, 0.05, 0.2};
  const CusumLimits l = *CusumLimitsOf(p);
  EXPECT_GT(l.s, p.p0);  // the reference rate lies between the two
  EXPECT_LT(l.s, p.p1);
  std::mt19937 rng(7);
  std::bernoulli_distribution fail(0.2);
  std::vector<bool> x;
  for (int i = 0; i < 60; ++i) x.push_back(fail(rng));
  const CusumCurve c = *Cusum(x, p);
  const double scale = std::log(p.p1 / p.p0) + std::log((1 - p.p0) / (1 - p.p1));
  int failures = 0;
  for (size_t n = 0; n < x.size(); ++n) {
    failures += x[n];
    const double successes = static_cast<double>(n + 1 - failures);
    // ln L(p1)/L(p0) of the first n+1 attempts, straight from the binomial likelihood.
    const double llr =
        failures * std::log(p.p1 / p.p0) + successes * std::log((1 - p.p1) / (1 - p.p0));
    EXPECT_NEAR(c.values[n] * scale, llr, 1e-9) << n;
  }
  // Wald's limits in the same units.
  EXPECT_NEAR(l.h1 * scale, std::log((1 - p.beta) / p.alpha), 1e-12);
  EXPECT_NEAR(-l.h0 * scale, std::log(p.beta / (1 - p.alpha)), 1e-12);
}

// The worked setting of the anaesthesia CUSUM literature (Kestin, Br J Anaesth 1995;75:805–9,
// used again for labour epidurals by Sivaprakasam & Purva, Clin Teach 2010): acceptable failure
// rate 10 %, unacceptable 20 %, α = β = 0.1. The published figures: P = ln 2 = 0.693,
// Q = ln(0.9/0.8) = 0.118, s = 0.145 (each success lowers the sum by 0.145, each failure raises it
// by 0.855), and both decision limits h = 2.71. A trainee without a failure therefore crosses the
// lower limit at attempt 19 (18 × 0.145 = 2.61 < 2.71 ≤ 19 × 0.145 = 2.76), and one failure costs
// six more successes (0.855 / 0.145 = 5.9).
TEST(CusumTest, KestinsWorkedFiguresForTenAndTwentyPercent) {
  const CusumParams p{0.10, 0.20, 0.10, 0.10};
  const CusumLimits l = *CusumLimitsOf(p);
  EXPECT_NEAR(l.s, 0.145, 5e-4);
  EXPECT_NEAR(1 - l.s, 0.855, 5e-4);
  EXPECT_NEAR(l.h0, 2.71, 5e-3);
  EXPECT_NEAR(l.h1, 2.71, 5e-3);
  EXPECT_EQ(*Cusum(std::vector<bool>(30, false), p)->proficient_at, 19);
  std::vector<bool> one_failure(40, false);
  one_failure[2] = true;  // the third attempt failed
  const CusumCurve c = *Cusum(one_failure, p);
  EXPECT_NEAR(c.values[2], -2 * 0.145 + 0.855, 2e-3);
  EXPECT_EQ(*c.proficient_at, 26);  // 25 successes: 25 × 0.145 − 0.855 = 2.77 ≥ 2.71
  // Three failures in the first five attempts cross the upper limit (3 × 0.855 − 2 × 0.145 =
  // 2.27 < 2.71; a fourth failure, 3.12, does).
  const CusumCurve bad = *Cusum({true, false, true, false, true, true}, p);
  EXPECT_EQ(*bad.unacceptable_at, 6);
}

TEST(CusumTest, AllSuccessesCrossIntoProficiencyAndAllFailuresOut) {
  const CusumParams p{0.1, 0.3, 0.05, 0.2};
  const CusumLimits l = *CusumLimitsOf(p);
  const CusumCurve good = *Cusum(std::vector<bool>(40, false), p);
  ASSERT_TRUE(good.proficient_at.has_value());
  EXPECT_EQ(*good.proficient_at, static_cast<int>(std::ceil(l.h0 / l.s)));
  EXPECT_FALSE(good.unacceptable_at.has_value());
  const CusumCurve bad = *Cusum(std::vector<bool>(40, true), p);
  ASSERT_TRUE(bad.unacceptable_at.has_value());
  EXPECT_EQ(*bad.unacceptable_at, static_cast<int>(std::ceil(l.h1 / (1 - l.s))));
  EXPECT_FALSE(bad.proficient_at.has_value());
  EXPECT_TRUE(Cusum({}, p)->values.empty());
}

TEST(CusumTest, WaldsErrorBoundsHoldBySimulation) {
  // A trainee at the acceptable rate p0 is called unacceptable first at most α/(1 − β) of the
  // time, and one at p1 called proficient first at most β/(1 − α) (Wald's bounds), over 20,000
  // simulated trainees each.
  const CusumParams p{0.1, 0.3, 0.05, 0.2};
  const CusumLimits l = *CusumLimitsOf(p);
  auto wrong_first = [&](double rate, bool want_proficient) {
    std::mt19937 rng(42);
    std::bernoulli_distribution fail(rate);
    int wrong = 0;
    for (int t = 0; t < 20000; ++t) {
      double s = 0;
      for (int n = 0; n < 2000; ++n) {
        s += fail(rng) ? 1 - l.s : -l.s;
        if (s <= -l.h0) {
          wrong += want_proficient ? 0 : 1;
          break;
        }
        if (s >= l.h1) {
          wrong += want_proficient ? 1 : 0;
          break;
        }
      }
    }
    return wrong / 20000.0;
  };
  EXPECT_LE(wrong_first(p.p0, true), p.alpha / (1 - p.beta));
  EXPECT_LE(wrong_first(p.p1, false), p.beta / (1 - p.alpha));
  EXPECT_GT(wrong_first(p.p0, true), 0.0);  // not vacuous: the test does err, within its bound
}

TEST(CusumTest, BadParametersAreRefusedByName) {
  EXPECT_EQ(CusumLimitsOf({0, 0.3, 0.05, 0.2}).error().field, "p0");
  EXPECT_EQ(CusumLimitsOf({0.3, 0.3, 0.05, 0.2}).error().field, "p1");
  EXPECT_EQ(CusumLimitsOf({0.1, 0.3, 1, 0.2}).error().field, "alpha");
  EXPECT_EQ(CusumLimitsOf({0.1, 0.3, 0.05, NAN}).error().field, "beta");
  EXPECT_EQ(Cusum({true}, {0.1, 1.5, 0.05, 0.2}).error().field, "p1");
}

}  // namespace
}  // namespace vsurg::scoring
