// Proficiency-based progression and learning curves: the rules a training programme runs on
// (the training programme). Pure functions over trial metrics; the store
// and the pages come on top.
//
// Targets (Gallagher et al., Ann Surg 2005: proficiency-based progression). An exercise names
// targets on metrics; an attempt passes when it meets every one (non-compensatory: a fast trial
// does not buy back a force peak, as in MScore). A trainee is proficient once `consecutive`
// attempts in a row passed; attempts may be limited per day.
//
// Expert benchmarks. A target can be derived from the experts' own attempts at the exercise:
//   mean ± k·SD: lower-is-better metrics target mean + k·SD, higher-is-better mean − k·SD;
//   best quartile (LAP Mentor's style): the boundary of the experts' best quarter, the 25th
//   percentile for lower-is-better metrics and the 75th for higher-is-better (linear
//   interpolation between order statistics, Hyndman & Fan type 7).
//
// CUSUM learning curve (Williams et al., Br J Surg 1992; Bolsin & Colson, Int J Qual Health Care
// 2000). Each attempt is a success (it passed) or a failure. With an acceptable failure rate p0,
// an unacceptable one p1, and the errors α (to call an acceptable trainee unacceptable) and β
// (the reverse):
//   P = ln(p1/p0), Q = ln((1 − p0)/(1 − p1)), s = Q / (P + Q)
//   S_0 = 0, S_n = S_{n−1} + (failure ? 1 − s : −s)
//   h1 = ln((1 − β)/α) / (P + Q),  h0 = ln((1 − α)/β) / (P + Q)
// S_n·(P + Q) is the log-likelihood ratio of p1 against p0 of the attempts so far (each failure
// adds ln(p1/p0), each success ln((1 − p1)/(1 − p0))), so the two limits are Wald's sequential
// probability ratio test: crossing h1 upward says the failure rate is p1 (unacceptable), crossing
// −h0 downward says it is p0: the attempt at which the curve crosses into proficiency.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/metrics.h"

namespace vsurg::scoring {

enum class Better { kLower, kHigher };

// The metrics a target may name, by the name the API uses, with their unit and direction.
struct MetricDef {
  std::string_view name;
  std::string_view unit;
  Better better;
  std::string_view label;  // as a trainee reads it: "peak force"
};
std::span<const MetricDef> ProficiencyMetrics();
const MetricDef* FindMetric(std::string_view name);
// A trial's value of a metric. Completion time of a trial never completed is +∞ (it fails any
// completion-time target).
double MetricValue(const TrialMetrics& m, const MetricDef& metric);

struct Target {
  std::string metric;  // a ProficiencyMetrics() name
  double value = 0;    // met when the trial's value is on the good side of it, or equal
};
// kInvalidArgument naming the target when its metric is unknown or its value not finite.
Status ValidateTargets(const std::vector<Target>& targets);

struct TargetCheck {
  std::string_view metric;  // a ProficiencyMetrics() name (static storage; "" when unknown)
  double value = 0, target = 0;
  bool met = false;
};
struct AttemptCheck {
  std::vector<TargetCheck> checks;  // in the targets' order
  bool passed = false;              // every target met (none: passed)
};
AttemptCheck CheckAttempt(const TrialMetrics& m, const std::vector<Target>& targets);

struct ProgressionRule {
  int consecutive = 2;           // passes in a row for proficiency (≥ 1)
  int max_attempts_per_day = 0;  // 0: no limit
};
struct Attempt {
  int64_t at_us = 0;  // when it ended, µs since the epoch
  TrialMetrics metrics;
};
struct Progress {
  std::vector<AttemptCheck> checks;  // one per attempt, oldest first
  int attempts = 0, passes = 0;
  int streak = 0;                    // passes in a row at the end
  std::optional<int> proficient_at;  // the attempt (1-based) that completed the first streak
  int attempts_today = 0;            // on the day of `now_us` (in the zone `utc_offset_s`)
  bool may_attempt = true;           // under the day's limit
};
// `attempts` oldest first. Days are counted in the zone `utc_offset_s` seconds east of UTC.
Progress EvaluateProgress(const std::vector<Attempt>& attempts, const std::vector<Target>& targets,
                          const ProgressionRule& rule, int64_t now_us, int64_t utc_offset_s = 0);

enum class BenchmarkMode { kMeanSd, kBestQuartile };
// A target from the experts' values of one metric (at least two, all finite); `k` is the SDs
// of the mean ± k·SD mode.
Expected<double> ExpertBenchmark(std::span<const double> values, Better better, BenchmarkMode mode,
                                 double k = 1.0);

struct CusumParams {
  double p0 = 0.1;      // acceptable failure rate
  double p1 = 0.3;      // unacceptable failure rate (> p0)
  double alpha = 0.05;  // risk of calling an acceptable trainee unacceptable
  double beta = 0.2;    // risk of calling an unacceptable trainee acceptable
};
struct CusumLimits {
  double s = 0;   // the decrement per success (and 1 − s the increment per failure)
  double h0 = 0;  // the lower limit is −h0: crossing it, the failure rate is p0
  double h1 = 0;  // the upper limit: crossing it, the failure rate is p1
};
// kInvalidArgument naming the parameter unless 0 < p0 < p1 < 1 and α, β in (0, 1).
Expected<CusumLimits> CusumLimitsOf(const CusumParams& p);
struct CusumCurve {
  CusumLimits limits;
  std::vector<double> values;          // S_1 … S_n
  std::optional<int> proficient_at;    // first attempt (1-based) with S ≤ −h0
  std::optional<int> unacceptable_at;  // first attempt with S ≥ h1
};
Expected<CusumCurve> Cusum(const std::vector<bool>& failures, const CusumParams& p);

}  // namespace vsurg::scoring
