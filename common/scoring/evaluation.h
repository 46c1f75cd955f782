// Weighted evaluation of a simulator, a session or a trainee by physicians (the coil-spring paper
// §4.4–4.5), with the reliability figures that say how far the raters agree.
//
// Nine indexes j = 1..9 (effectiveness, force-feedback performance, real-time performance,
// system stability, deformation efficiency, fidelity, visual fluency, immersion, texture), each
// scored 0–10 by every evaluator; evaluators in three groups g (intern, associate chief, chief).
//
//   the coil-spring paper eq. 9   M_j = Σ_g w_g · (1/n_g) Σ_{i∈g} x_ij          (group weights
//   0.2/0.3/0.5) the coil-spring paper eq. 10  s_j = (1/n) Σ_i (x_ij − M_j)²                 (all n
//   raters, about M_j) the coil-spring paper eq. 11  N   = Σ_j w_j · M_j (0.15×4, 0.10×3, 0.05×2)
//
// A group with no rater: the present groups' weights are divided by their sum (the report lists
// the absent groups and sets `renormalised`). Weights are configuration (WeightSet) and every
// report carries the set it used.
//
// Reliability (not in the paper; what a reader of a report needs to trust it):
//   ICC(2,k), two-way random effects, absolute agreement, mean of k raters (Shrout & Fleiss
//   1979; McGraw & Wong 1996 "ICC(A,k)"), on an n targets × k raters matrix:
//     ICC(2,k) = (MS_R − MS_E) / (MS_R + (MS_C − MS_E)/n)
//   MS_R between targets, MS_C between raters, MS_E residual. Per index it needs several subjects
//   scored by the same raters (the paper's three models); for one subject the report gives the
//   ICC over the nine indexes as targets (do the raters agree on the profile).
//   Cronbach's α across the nine indexes, raters as cases:
//     α = k/(k−1) · (1 − Σ_j var(x_·j) / var(Σ_j x_·j))
// A figure that is undefined (fewer than two raters, zero variance) is NaN; the JSON writers turn
// it into null.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/vocabulary.h"

namespace vsurg::scoring {

struct WeightSet {
  std::string name = "coil-spring-paper";
  std::array<double, kGroupCount> group = {0.2, 0.3, 0.5};
  std::array<double, kIndexCount> index = {0.15, 0.15, 0.15, 0.15, 0.10, 0.10, 0.10, 0.05, 0.05};
};
// Each weight finite and ≥ 0, each family summing to 1 (±1e-9), a name.
Status ValidateWeights(const WeightSet& w);

struct Rating {
  std::string evaluator;
  EvaluatorGroup group = EvaluatorGroup::kIntern;
  std::array<double, kIndexCount> scores{};  // 0–10
  int line = 0;                              // where it was read from (CSV line), 0: not read
};
// Scores finite and within 0–10, an evaluator id; the error names the field ("scores[3]").
Status ValidateRating(const Rating& r);

struct EvaluationReport {
  int raters = 0;
  std::array<int, kGroupCount> raters_per_group{};
  std::array<double, kGroupCount> group_weights_used{};  // after renormalisation
  bool renormalised = false;
  std::vector<std::string> absent_groups;
  std::array<double, kIndexCount> index_means{};      // M_j, eq. 9
  std::array<double, kIndexCount> index_variances{};  // s_j, eq. 10
  double comprehensive = 0;                           // N, eq. 11
  double icc2k_indexes = 0;   // ICC(2,k) with the indexes as targets (NaN if undefined)
  double cronbach_alpha = 0;  // across indexes (NaN if undefined)
  WeightSet weights;
};

// One subject (a session, a trainee or a simulator model). At least one rating, each valid;
// one rating per evaluator.
Expected<EvaluationReport> Evaluate(std::span<const Rating> ratings, const WeightSet& weights);

// Several subjects rated by the same evaluators (the paper's three models): a report each, and
// ICC(2,k) per index over the subjects (NaN when fewer than two subjects or raters). Only the
// evaluators who rated every subject enter the ICC.
struct SubjectRatings {
  std::string subject;
  std::vector<Rating> ratings;
};
struct ComparisonReport {
  std::vector<EvaluationReport> subjects;  // in the order given
  std::array<double, kIndexCount> icc2k_per_index{};
  int common_raters = 0;
};
Expected<ComparisonReport> Compare(std::span<const SubjectRatings> subjects,
                                   const WeightSet& weights);

// Shrout–Fleiss ICC(2,k) of a row-major n×k matrix (targets × raters); NaN when undefined.
double Icc2k(std::span<const double> x, int n, int k);
// Cronbach's α of a row-major n×k matrix (cases × items); NaN when undefined.
double CronbachAlpha(std::span<const double> x, int n, int k);

// Training effect (the coil-spring paper §4.5): each trainee's score at a moment is the mean of the
// evaluators' scores; per trainee group and moment, the mean and the population variance of
// those trainee scores.
struct TrainingScore {
  std::string trainee;
  std::string trainee_group;
  double moment_min = 0;  // training time so far, minutes (0, 20, 40 in the paper)
  std::string evaluator;
  double score = 0;  // 0–10
};
struct TrainingCell {
  std::string trainee_group;
  double moment_min = 0;
  int trainees = 0;
  double mean = 0;
  double variance = 0;
};
// Sorted by group, then moment.
Expected<std::vector<TrainingCell>> TrainingEffect(std::span<const TrainingScore> scores);

}  // namespace vsurg::scoring
