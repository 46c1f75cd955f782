#include "common/scoring/proficiency.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace vsurg::scoring {
namespace {

constexpr std::array<MetricDef, 22> kMetrics = {{
    {"completion_time_s", "s", Better::kLower, "completion time"},
    {"task_error", "rad or m", Better::kLower, "task error"},
    {"peak_force_n", "N", Better::kLower, "peak force"},
    {"time_over_force_limit_s", "s", Better::kLower, "time over the force limit"},
    {"path_length_m", "m", Better::kLower, "path length"},
    {"rms_jerk", "m/s³", Better::kLower, "RMS jerk"},
    {"overload_events", "", Better::kLower, "overload events"},
    {"score", "/10", Better::kHigher, "score"},
    // The share of the trial's samples an instructor's hand weighed in (four-handed training): a
    // target of 0 asks for the exercise to be passed unguided.
    {"guided_share", "", Better::kLower, "share of the trial guided"},
    // A palpation's (palpation.h): what it found, where, and how much of the tissue it examined.
    {"lumps_missed", "", Better::kLower, "lumps missed"},
    {"false_marks", "", Better::kLower, "false marks"},
    {"localisation_error_m", "m", Better::kLower, "localisation error"},
    {"coverage", "", Better::kHigher, "share of the surface examined"},
    // A needle insertion's (needle.h): where the tip was placed, the aim, the tissue it cost.
    {"depth_error_m", "m", Better::kLower, "needle depth error"},
    {"path_deviation_m", "m", Better::kLower, "needle path deviation"},
    {"extra_punctures", "", Better::kLower, "punctures beyond the path's own"},
    {"back_wall_breaches", "", Better::kLower, "back-wall breaches"},
    {"lateral_strain", "", Better::kLower, "lateral tissue strain"},
    // A pattern cut's (cut.h): how far it strayed, what it cut or tore off the line, its lifts.
    {"cut_deviation_max_m", "m", Better::kLower, "largest deviation from the line"},
    {"cut_outside_m", "m", Better::kLower, "length cut outside the band"},
    {"torn_length_m", "m", Better::kLower, "length torn by pulling"},
    {"cut_lifts", "", Better::kLower, "blade lifts mid-cut"},
}};

// Equal within rounding counts as met: a benchmark from experts who all reached the same value
// (a force pinned at the device's limit: SD 0) is that value, and a trainee who reaches it too,
// computed in another order, must not fail by 1e-10 N.
bool Met(double value, double target, Better better) {
  const double slack = 1e-9 * std::max(std::abs(target), 1.0);
  return better == Better::kLower ? value <= target + slack : value >= target - slack;
}

int64_t FloorDiv(int64_t a, int64_t b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)) ? 1 : 0);
}

// The day of `at_us` in the zone `offset_s` east of UTC, as a day number.
int64_t Day(int64_t at_us, int64_t offset_s) {
  return FloorDiv(FloorDiv(at_us, 1'000'000) + offset_s, 86'400);
}

}  // namespace

std::span<const MetricDef> ProficiencyMetrics() {
  return kMetrics;
}

const MetricDef* FindMetric(std::string_view name) {
  for (const MetricDef& m : kMetrics)
    if (m.name == name) return &m;
  return nullptr;
}

double MetricValue(const TrialMetrics& m, const MetricDef& metric) {
  const std::string_view n = metric.name;
  if (n == "completion_time_s")
    return m.completed ? m.completion_time : std::numeric_limits<double>::infinity();
  if (n == "task_error") return m.task_error;
  if (n == "peak_force_n") return m.peak_force;
  if (n == "time_over_force_limit_s") return m.time_over_force_limit;
  if (n == "path_length_m") return m.path_length;
  if (n == "rms_jerk") return m.rms_jerk;
  if (n == "overload_events") return m.overload_events;
  if (n == "guided_share") return m.guided_share;
  if (n == "lumps_missed") return m.lumps - m.lumps_found;
  if (n == "false_marks") return m.false_marks;
  if (n == "localisation_error_m")  // no lump found: no credit for where
    return m.lumps_found > 0 || m.lumps == 0 ? m.localisation_error
                                             : std::numeric_limits<double>::infinity();
  if (n == "coverage") return m.coverage;
  // A needle never placed in the tissue has no placement to credit.
  if (n == "depth_error_m")
    return m.punctures > 0 ? m.depth_error : std::numeric_limits<double>::infinity();
  if (n == "path_deviation_m")
    return m.punctures > 0 ? m.path_deviation : std::numeric_limits<double>::infinity();
  if (n == "extra_punctures") return m.extra_punctures;
  if (n == "back_wall_breaches") return m.back_wall_breaches;
  if (n == "lateral_strain") return m.lateral_strain;
  if (n == "cut_deviation_max_m") return m.cut_deviation_max;
  if (n == "cut_outside_m") return m.cut_outside;
  if (n == "torn_length_m") return m.torn_length;
  if (n == "cut_lifts") return m.cut_lifts;
  return m.score;
}

Status ValidateTargets(const std::vector<Target>& targets) {
  for (size_t i = 0; i < targets.size(); ++i) {
    const std::string field = "targets[" + std::to_string(i) + "]";
    if (!FindMetric(targets[i].metric))
      return InvalidArgument(field, "unknown metric '" + targets[i].metric + "'");
    if (!std::isfinite(targets[i].value)) return InvalidArgument(field, "the value must be finite");
  }
  return Status::Ok();
}

AttemptCheck CheckAttempt(const TrialMetrics& m, const std::vector<Target>& targets) {
  AttemptCheck out;
  out.passed = true;
  out.checks.reserve(targets.size());
  for (const Target& t : targets) {
    TargetCheck c{"", std::numeric_limits<double>::quiet_NaN(), t.value, false};
    if (const MetricDef* def = FindMetric(t.metric)) {
      c.metric = def->name;
      c.value = MetricValue(m, *def);
      c.met = !std::isnan(c.value) && Met(c.value, t.value, def->better);
    }
    out.passed = out.passed && c.met;
    out.checks.push_back(std::move(c));
  }
  return out;
}

Progress EvaluateProgress(const std::vector<Attempt>& attempts, const std::vector<Target>& targets,
                          const ProgressionRule& rule, int64_t now_us, int64_t utc_offset_s) {
  Progress p;
  p.checks.reserve(attempts.size());
  const int need = std::max(1, rule.consecutive);
  const int64_t today = Day(now_us, utc_offset_s);
  for (const Attempt& a : attempts) {
    AttemptCheck c = CheckAttempt(a.metrics, targets);
    ++p.attempts;
    if (Day(a.at_us, utc_offset_s) == today) ++p.attempts_today;
    if (c.passed) {
      ++p.passes;
      ++p.streak;
      if (!p.proficient_at && p.streak >= need) p.proficient_at = p.attempts;
    } else {
      p.streak = 0;
    }
    p.checks.push_back(std::move(c));
  }
  p.may_attempt = rule.max_attempts_per_day <= 0 || p.attempts_today < rule.max_attempts_per_day;
  return p;
}

Expected<double> ExpertBenchmark(std::span<const double> values, Better better, BenchmarkMode mode,
                                 double k) {
  if (values.size() < 2)
    return InvalidArgument("experts", "a benchmark needs the attempts of at least two experts");
  for (double v : values)
    if (!std::isfinite(v)) return InvalidArgument("experts", "an expert's value is not finite");
  if (mode == BenchmarkMode::kMeanSd) {
    if (!std::isfinite(k) || k < 0) return InvalidArgument("k", "must be finite and ≥ 0");
    double mean = 0;
    for (double v : values) mean += v;
    mean /= static_cast<double>(values.size());
    double ss = 0;
    for (double v : values) ss += (v - mean) * (v - mean);
    const double sd = std::sqrt(ss / static_cast<double>(values.size() - 1));  // sample SD
    return better == Better::kLower ? mean + k * sd : mean - k * sd;
  }
  std::vector<double> v(values.begin(), values.end());
  std::sort(v.begin(), v.end());
  const double q = better == Better::kLower ? 0.25 : 0.75;
  const double h = q * static_cast<double>(v.size() - 1);  // type 7
  const auto lo = static_cast<size_t>(std::floor(h));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (h - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

Expected<CusumLimits> CusumLimitsOf(const CusumParams& p) {
  if (!(p.p0 > 0 && p.p0 < 1)) return InvalidArgument("p0", "must be within (0, 1)");
  if (!(p.p1 > p.p0 && p.p1 < 1)) return InvalidArgument("p1", "must be within (p0, 1)");
  if (!(p.alpha > 0 && p.alpha < 1)) return InvalidArgument("alpha", "must be within (0, 1)");
  if (!(p.beta > 0 && p.beta < 1)) return InvalidArgument("beta", "must be within (0, 1)");
  const double P = std::log(p.p1 / p.p0), Q = std::log((1 - p.p0) / (1 - p.p1));
  CusumLimits l;
  l.s = Q / (P + Q);
  l.h1 = std::log((1 - p.beta) / p.alpha) / (P + Q);
  l.h0 = std::log((1 - p.alpha) / p.beta) / (P + Q);
  return l;
}

Expected<CusumCurve> Cusum(const std::vector<bool>& failures, const CusumParams& p) {
  auto limits = CusumLimitsOf(p);
  if (!limits.ok()) return limits.error();
  CusumCurve c;
  c.limits = *limits;
  double s = 0;
  for (size_t i = 0; i < failures.size(); ++i) {
    s += failures[i] ? 1 - c.limits.s : -c.limits.s;
    c.values.push_back(s);
    const int n = static_cast<int>(i) + 1;
    if (!c.proficient_at && s <= -c.limits.h0) c.proficient_at = n;
    if (!c.unacceptable_at && s >= c.limits.h1) c.unacceptable_at = n;
  }
  return c;
}

}  // namespace vsurg::scoring
