#include "common/scoring/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <utility>

namespace vsurg::scoring {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Status ValidateFamily(std::span<const double> w, const char* field) {
  double sum = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    if (!std::isfinite(w[i]) || w[i] < 0)
      return InvalidArgument(std::string(field) + "[" + std::to_string(i) + "]",
                             "weight must be finite and >= 0");
    sum += w[i];
  }
  if (std::abs(sum - 1.0) > 1e-9)
    return InvalidArgument(field,
                           "weights must sum to 1 (they sum to " + std::to_string(sum) + ")");
  return Status::Ok();
}

}  // namespace

Status ValidateWeights(const WeightSet& w) {
  if (w.name.empty()) return InvalidArgument("name", "a weight set needs a name");
  if (Status s = ValidateFamily(w.group, "group_weights"); !s.ok()) return s;
  return ValidateFamily(w.index, "index_weights");
}

Status ValidateRating(const Rating& r) {
  if (r.evaluator.empty()) return InvalidArgument("evaluator", "an evaluator id is required");
  const int g = static_cast<int>(r.group);
  if (g < 0 || g >= kGroupCount) return InvalidArgument("group", "unknown evaluator group");
  for (int j = 0; j < kIndexCount; ++j) {
    if (!IsValidScore(r.scores[j]))
      return InvalidArgument("scores[" + std::to_string(j) + "]",
                             std::string(kIndexNames[j]) + " score must be within 0..10");
  }
  return Status::Ok();
}

double Icc2k(std::span<const double> x, int n, int k) {
  if (n < 2 || k < 2 || x.size() != static_cast<size_t>(n) * k) return kNaN;
  double grand = 0;
  for (double v : x) grand += v;
  grand /= static_cast<double>(n * k);
  double ss_rows = 0, ss_cols = 0, ss_total = 0;
  for (int i = 0; i < n; ++i) {
    double m = 0;
    for (int j = 0; j < k; ++j) m += x[i * k + j];
    m /= k;
    ss_rows += k * (m - grand) * (m - grand);
  }
  for (int j = 0; j < k; ++j) {
    double m = 0;
    for (int i = 0; i < n; ++i) m += x[i * k + j];
    m /= n;
    ss_cols += n * (m - grand) * (m - grand);
  }
  for (double v : x) ss_total += (v - grand) * (v - grand);
  const double ms_r = ss_rows / (n - 1);
  const double ms_c = ss_cols / (k - 1);
  const double ms_e = std::max(0.0, ss_total - ss_rows - ss_cols) / ((n - 1.0) * (k - 1.0));
  const double den = ms_r + (ms_c - ms_e) / n;
  // Undefined: no variance at all, or a non-positive denominator (the raters disagree so much
  // more than the targets differ that the estimator breaks down; read it as no agreement).
  // A negative estimate with a positive denominator is kept.
  if (!(ss_total > 1e-12) || !(den > 1e-12)) return kNaN;
  return (ms_r - ms_e) / den;
}

double CronbachAlpha(std::span<const double> x, int n, int k) {
  if (n < 2 || k < 2 || x.size() != static_cast<size_t>(n) * k) return kNaN;
  auto variance = [n](auto&& value) {
    double mean = 0;
    for (int i = 0; i < n; ++i) mean += value(i);
    mean /= n;
    double v = 0;
    for (int i = 0; i < n; ++i) v += (value(i) - mean) * (value(i) - mean);
    return v / (n - 1);
  };
  double item_sum = 0;
  for (int j = 0; j < k; ++j) item_sum += variance([&](int i) { return x[i * k + j]; });
  const double total = variance([&](int i) {
    double s = 0;
    for (int j = 0; j < k; ++j) s += x[i * k + j];
    return s;
  });
  if (!(total > 1e-12)) return kNaN;
  return k / (k - 1.0) * (1.0 - item_sum / total);
}

Expected<EvaluationReport> Evaluate(std::span<const Rating> ratings, const WeightSet& weights) {
  if (Status s = ValidateWeights(weights); !s.ok()) return s.error();
  if (ratings.empty()) return InvalidArgument("ratings", "no ratings to evaluate");
  std::set<std::string> seen;
  for (size_t i = 0; i < ratings.size(); ++i) {
    if (Status s = ValidateRating(ratings[i]); !s.ok()) {
      Error e = s.error();
      e.field = "ratings[" + std::to_string(i) + "]." + e.field;
      return e;
    }
    if (!seen.insert(ratings[i].evaluator).second)
      return InvalidArgument("ratings[" + std::to_string(i) + "].evaluator",
                             "evaluator '" + ratings[i].evaluator + "' rated this subject twice");
  }

  EvaluationReport r;
  r.weights = weights;
  r.raters = static_cast<int>(ratings.size());
  std::array<std::array<double, kIndexCount>, kGroupCount> group_sum{};
  for (const Rating& rating : ratings) {
    const int g = static_cast<int>(rating.group);
    ++r.raters_per_group[g];
    for (int j = 0; j < kIndexCount; ++j) group_sum[g][j] += rating.scores[j];
  }
  double present = 0;
  for (int g = 0; g < kGroupCount; ++g) {
    if (r.raters_per_group[g] > 0) {
      present += weights.group[g];
    } else {
      r.absent_groups.emplace_back(kGroupNames[g]);
    }
  }
  if (!(present > 0))
    return InvalidArgument("group_weights", "every group that rated has weight 0");
  r.renormalised = !r.absent_groups.empty();
  for (int g = 0; g < kGroupCount; ++g)
    r.group_weights_used[g] = r.raters_per_group[g] > 0 ? weights.group[g] / present : 0.0;

  // eq. 9 and eq. 11
  for (int j = 0; j < kIndexCount; ++j) {
    double m = 0;
    for (int g = 0; g < kGroupCount; ++g)
      if (r.raters_per_group[g] > 0)
        m += r.group_weights_used[g] * group_sum[g][j] / r.raters_per_group[g];
    r.index_means[j] = m;
    r.comprehensive += weights.index[j] * m;
  }
  // eq. 10: population variance of every rater's score about M_j
  for (int j = 0; j < kIndexCount; ++j) {
    double v = 0;
    for (const Rating& rating : ratings)
      v += (rating.scores[j] - r.index_means[j]) * (rating.scores[j] - r.index_means[j]);
    r.index_variances[j] = v / r.raters;
  }

  // Reliability: indexes × raters for the ICC, raters × indexes for α.
  const int n = r.raters;
  std::vector<double> by_index(static_cast<size_t>(kIndexCount) * n);
  std::vector<double> by_rater(static_cast<size_t>(n) * kIndexCount);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < kIndexCount; ++j) {
      by_index[j * n + i] = ratings[i].scores[j];
      by_rater[i * kIndexCount + j] = ratings[i].scores[j];
    }
  r.icc2k_indexes = Icc2k(by_index, kIndexCount, n);
  r.cronbach_alpha = CronbachAlpha(by_rater, n, kIndexCount);
  return r;
}

Expected<ComparisonReport> Compare(std::span<const SubjectRatings> subjects,
                                   const WeightSet& weights) {
  if (subjects.empty()) return InvalidArgument("subjects", "no subjects to compare");
  ComparisonReport out;
  std::vector<std::map<std::string, const Rating*>> by_evaluator(subjects.size());
  for (size_t s = 0; s < subjects.size(); ++s) {
    auto report = Evaluate(subjects[s].ratings, weights);
    if (!report.ok()) {
      Error e = report.error();
      e.field = "subjects[" + std::to_string(s) + "]." + e.field;
      return e;
    }
    out.subjects.push_back(std::move(report).value());
    for (const Rating& r : subjects[s].ratings) by_evaluator[s][r.evaluator] = &r;
  }
  std::vector<std::string> common;
  for (const auto& [evaluator, rating] : by_evaluator[0]) {
    bool everywhere = true;
    for (size_t s = 1; s < subjects.size(); ++s)
      everywhere = everywhere && by_evaluator[s].count(evaluator) > 0;
    if (everywhere) common.push_back(evaluator);
  }
  out.common_raters = static_cast<int>(common.size());
  const int n = static_cast<int>(subjects.size());
  const int k = out.common_raters;
  std::vector<double> x(static_cast<size_t>(n) * k);
  for (int j = 0; j < kIndexCount; ++j) {
    for (int s = 0; s < n; ++s)
      for (int c = 0; c < k; ++c) x[s * k + c] = by_evaluator[s].at(common[c])->scores[j];
    out.icc2k_per_index[j] = Icc2k(x, n, k);
  }
  return out;
}

Expected<std::vector<TrainingCell>> TrainingEffect(std::span<const TrainingScore> scores) {
  // (group, moment) → trainee → (sum, count) of the evaluators' scores
  std::map<std::pair<std::string, double>, std::map<std::string, std::pair<double, int>>> cells;
  std::set<std::tuple<std::string, double, std::string>> seen;
  for (size_t i = 0; i < scores.size(); ++i) {
    const TrainingScore& s = scores[i];
    const std::string at = "scores[" + std::to_string(i) + "]";
    if (s.trainee.empty()) return InvalidArgument(at + ".trainee", "a trainee id is required");
    if (s.trainee_group.empty()) return InvalidArgument(at + ".trainee_group", "required");
    if (!std::isfinite(s.moment_min) || s.moment_min < 0)
      return InvalidArgument(at + ".moment_min", "must be finite and >= 0 minutes");
    if (!std::isfinite(s.score) || s.score < kMinScore || s.score > kMaxScore)
      return InvalidArgument(at + ".score", "must be within 0..10");
    if (!seen.insert({s.trainee, s.moment_min, s.evaluator}).second)
      return InvalidArgument(at + ".evaluator", "evaluator '" + s.evaluator +
                                                    "' scored this trainee twice at " +
                                                    std::to_string(s.moment_min) + " min");
    auto& [sum, count] = cells[{s.trainee_group, s.moment_min}][s.trainee];
    sum += s.score;
    ++count;
  }
  std::vector<TrainingCell> out;
  for (const auto& [key, trainees] : cells) {
    TrainingCell c;
    c.trainee_group = key.first;
    c.moment_min = key.second;
    c.trainees = static_cast<int>(trainees.size());
    for (const auto& [name, sc] : trainees) c.mean += sc.first / sc.second;
    c.mean /= c.trainees;
    for (const auto& [name, sc] : trainees) {
      const double d = sc.first / sc.second - c.mean;
      c.variance += d * d;
    }
    c.variance /= c.trainees;
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace vsurg::scoring
