// Pattern cutting's metrics (cut.h).
#include "common/scoring/cut.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/scoring/proficiency.h"

namespace vsurg::scoring {

namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;
constexpr double kStep = 0.25e-3;  // m, the cut's path sampled at least this often

double Clamp01(double v) {
  return std::clamp(v, 0.0, 1.0);
}

}  // namespace

double CutPattern::Length() const {
  return kind == Kind::kLine ? std::hypot(bx - ax, by - ay) : kTwoPi * radius;
}

void CutPattern::At(double u, double& x, double& y) const {
  if (kind == Kind::kLine) {
    x = ax + u * (bx - ax), y = ay + u * (by - ay);
  } else {
    x = cx + radius * std::cos(kTwoPi * u), y = cy + radius * std::sin(kTwoPi * u);
  }
}

double CutPattern::Distance(double x, double y, double* u) const {
  if (kind == Kind::kLine) {
    const double ex = bx - ax, ey = by - ay, e2 = ex * ex + ey * ey;
    const double t = e2 > 0 ? std::clamp(((x - ax) * ex + (y - ay) * ey) / e2, 0.0, 1.0) : 0.0;
    if (u) *u = t;
    return std::hypot(x - (ax + t * ex), y - (ay + t * ey));
  }
  if (u) {
    const double a = std::atan2(y - cy, x - cx);
    *u = (a < 0 ? a + kTwoPi : a) / kTwoPi;
  }
  return std::abs(std::hypot(x - cx, y - cy) - radius);
}

void CutRecorder::AddSample(double t, double x, double y, bool through, double force,
                            double force_limit) {
  if (!std::isfinite(t) || !std::isfinite(x) || !std::isfinite(y)) return;
  t_ = t;
  if (std::isfinite(force)) peak_ = std::max(peak_, force);
  if (has_last_) {
    const double dt = t - last_t_;
    if (force > force_limit && dt > 0) over_ += dt;
    // The travel along the pattern, once the cut has begun: through the tissue, or lifted.
    if (started_ && p_.Distance(x, y) <= 2 * p_.band) {
      const double d = std::hypot(x - last_x_, y - last_y_);
      along_ += d;
      if (through) along_through_ += d;
    }
  }
  if (started_ && was_through_ && !through && complete_at_ < 0) ++lifts_;  // mid-cut only
  started_ = started_ || through;
  was_through_ = through;
  last_t_ = t, last_x_ = x, last_y_ = y, has_last_ = true;
}

void CutRecorder::AddCut(double ax, double ay, double bx, double by) {
  const double len = std::hypot(bx - ax, by - ay);
  if (!std::isfinite(len)) return;
  // Sampled finer than a coverage bin, so that a cut along the pattern covers every bin it passes.
  const double step = std::min(kStep, 0.5 * p_.Length() / kBins);
  const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
  for (int i = 1; i <= n; ++i) {
    const double x = ax + (bx - ax) * i / n, y = ay + (by - ay) * i / n, piece = len / n;
    double u = 0;
    const double d = p_.Distance(x, y, &u);
    dev2_ += d * d * piece, dev_max_ = std::max(dev_max_, d), length_ += piece;
    if (d > p_.band) {
      outside_ += piece;
      continue;
    }
    covered_[std::min(kBins - 1, static_cast<int>(u * kBins))] = true;
  }
  if (complete_at_ < 0) {
    const int covered = static_cast<int>(std::count(covered_.begin(), covered_.end(), true));
    const bool enough = covered >= 0.95 * kBins;
    if (enough && (p_.kind == CutPattern::Kind::kLine || freed_at_ >= 0)) complete_at_ = t_;
  }
}

void CutRecorder::PieceFreed(double t) {
  if (freed_at_ < 0) freed_at_ = t;
  const int covered = static_cast<int>(std::count(covered_.begin(), covered_.end(), true));
  if (complete_at_ < 0 && covered >= 0.95 * kBins) complete_at_ = t;
}

CutMetrics CutRecorder::Complete(const CutTask& task) const {
  CutMetrics m;
  m.cut_length = length_;
  m.deviation_rms = length_ > 0 ? std::sqrt(dev2_ / length_) : 0;
  m.deviation_max = dev_max_;
  m.outside_length = outside_;
  m.coverage = static_cast<double>(std::count(covered_.begin(), covered_.end(), true)) / kBins;
  m.through_share = along_ > 0 ? along_through_ / along_ : 0;
  m.lifts = lifts_;
  m.piece_freed = freed_at_ >= 0;
  m.duration = t_;
  m.completed = complete_at_ >= 0 && complete_at_ <= task.time_limit;
  m.completion_time = m.completed ? complete_at_ : 0;
  m.peak_force = peak_;
  m.time_over_limit = over_;
  m.torn_length = torn_;
  const double band = task.pattern.band > 0 ? task.pattern.band : 0.002;
  const double accuracy = length_ > 0 ? Clamp01(1 - m.deviation_rms / band) : 0;
  const double efficiency =
      m.completed ? Clamp01(task.expert_time / std::max(m.completion_time, 1e-3)) : 0;
  const double care = Clamp01(1 - (outside_ + torn_) / std::max(task.pattern.Length(), 1e-3) -
                              0.1 * lifts_ - over_ / std::max(t_, 1e-3));
  m.score = 10 * (0.4 * accuracy + 0.3 * m.coverage + 0.15 * efficiency + 0.15 * care);
  return m;
}

namespace {

struct CutMetricDef {
  const char* name;
  bool lower_is_better;
  double (*value)(const CutMetrics&);
};

constexpr CutMetricDef kCutMetrics[] = {
    {"deviation_rms_m", true, [](const CutMetrics& m) { return m.deviation_rms; }},
    {"deviation_max_m", true, [](const CutMetrics& m) { return m.deviation_max; }},
    {"outside_length_m", true, [](const CutMetrics& m) { return m.outside_length; }},
    {"torn_length_m", true, [](const CutMetrics& m) { return m.torn_length; }},
    {"lifts", true, [](const CutMetrics& m) { return static_cast<double>(m.lifts); }},
    {"completion_time_s", true,
     [](const CutMetrics& m) { return m.completed ? m.completion_time : INFINITY; }},
    {"coverage", false, [](const CutMetrics& m) { return m.coverage; }},
};

}  // namespace

Expected<std::vector<CutTarget>> CutTargetsFromExperts(const std::vector<CutMetrics>& experts,
                                                       double k) {
  if (experts.size() < 2)
    return InvalidArgument("experts", "experts: targets need at least two expert runs");
  for (const CutMetrics& e : experts)
    if (!e.completed) return InvalidArgument("experts", "experts: every expert run must complete");
  std::vector<CutTarget> targets;
  for (const CutMetricDef& d : kCutMetrics) {
    std::vector<double> values;
    for (const CutMetrics& e : experts) values.push_back(d.value(e));
    auto v = ExpertBenchmark(values, d.lower_is_better ? Better::kLower : Better::kHigher,
                             BenchmarkMode::kMeanSd, k);
    if (!v.ok()) return v.error();
    targets.push_back({d.name, d.lower_is_better, *v});
  }
  return targets;
}

std::vector<CutCheck> CheckCut(const CutMetrics& m, const std::vector<CutTarget>& targets) {
  std::vector<CutCheck> checks;
  for (const CutTarget& t : targets) {
    for (const CutMetricDef& d : kCutMetrics) {
      if (t.metric != d.name) continue;
      const double v = d.value(m);
      checks.push_back({t.metric, v, t.value, t.lower_is_better ? v <= t.value : v >= t.value});
    }
  }
  return checks;
}

std::vector<std::string> ExplainCut(const CutMetrics& m, const CutTask& task) {
  std::vector<std::string> why;
  const double band_mm = task.pattern.band * 1e3;
  if (m.deviation_rms > 0.5 * task.pattern.band)
    why.push_back("the cut strayed from the line: " + std::to_string(m.deviation_rms * 1e3) +
                  " mm RMS in a band of ±" + std::to_string(band_mm) + " mm");
  if (m.outside_length > 0)
    why.push_back(std::to_string(m.outside_length * 1e3) + " mm cut outside the band");
  if (m.coverage < 0.95)
    why.push_back("the pattern was cut for " + std::to_string(static_cast<int>(m.coverage * 100)) +
                  "% of its length");
  if (m.torn_length > 0)
    why.push_back(std::to_string(m.torn_length * 1e3) + " mm torn by pulling instead of cut");
  if (m.lifts > 0) why.push_back("the blade was lifted out " + std::to_string(m.lifts) + " times");
  if (m.time_over_limit > 0) why.push_back("pressed harder than the force limit");
  if (m.completed && m.completion_time > 2 * task.expert_time) why.push_back("slow");
  return why;
}

}  // namespace vsurg::scoring
