#include "common/scoring/trial_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/scoring/cut.h"
#include "common/scoring/needle.h"
#include "common/scoring/palpation.h"

namespace vsurg::scoring {

const char* TaskKindName(TaskKind kind) {
  switch (kind) {
    case TaskKind::kTwist:
      return "twist";
    case TaskKind::kPress:
      return "press";
    case TaskKind::kPalpate:
      return "palpate";
    case TaskKind::kInsert:
      return "insert";
    case TaskKind::kCut:
      return "cut";
  }
  return "twist";
}

TaskDisplayUnit DisplayUnitOf(TaskKind kind) {
  if (kind == TaskKind::kTwist) return {180.0 / 3.14159265358979323846, "deg"};
  return {1e3, "mm"};
}

namespace {

constexpr double kGrid = 0.01;                            // s, the jerk's grid
constexpr double kOmega = 2.0 * 3.14159265358979 * 10.0;  // rad/s, the low-pass corner
constexpr int kMaxGridSteps = 128;       // a longer gap restarts the grid (and the jerk's history)
constexpr double kGapS = 2e-3;           // s, a longer step is a gap: bridged by a parabola
constexpr double kMaxBridgedGapS = 1.0;  // s, a longer step is a clock jump: a chord
constexpr int kMaxPieces = 100;          // 1 ms pieces of a bridged gap
constexpr double kVelocityBase = 1e-3;   // s, the shortest span the velocity is taken over

}  // namespace

void TrialRecorder::Add(double time, const Eigen::Vector3d& tip, double quantity, double force,
                        bool overload) {
  if (!std::isfinite(time) || !tip.allFinite() || !std::isfinite(quantity) || !std::isfinite(force))
    return;
  if (samples_ > 0 && !(time > t_last_)) return;  // out of order or repeated: ignore
  if (samples_ == 0) t0_ = time;
  const double dt = samples_ > 0 ? time - t_last_ : 0.0;
  if (samples_ > 0) {
    path_ += (tip - last_tip_).norm();
    if (force > task_.force_limit) over_ += dt;
  }
  // One-pole low-pass at 10 Hz, y' = ω(u − y), then the filtered tip on a uniform grid of
  // kGrid = 10 ms, then the third difference: jerk ≈ (x₀ − 3x₁ + 3x₂ − x₃) / kGrid³. The grid is
  // well above the filter's band, and a sample's timing jitter δ moves a grid value by only
  // about |v|·δ, where a third difference over the raw 1 ms spacing amplified it by 10⁹.
  // Between two samples the tip is taken to move linearly (first-order hold; holding the new tip
  // over the step instead read a loaded host's late cycles as jerk: 19 m/s³ against 0.05).
  // Across a gap (a stalled station, a burst of lost datagrams) a straight chord is not how a
  // hand moves: it bends the path twice, and at the onset of a reach a 30 ms gap read as 7.6 m/s³
  // against 4.0 for the same movement without it. There the tip follows the parabola that leaves
  // the last sample with its velocity (over ≥ kVelocityBase) and reaches the new one, in 1 ms
  // pieces: the path stays C¹ where the data ended, which is all a gap lets one know.
  const bool first = samples_ == 0;
  if (first || time - next_grid_ > kMaxGridSteps * kGrid) {
    if (first) filtered_ = tip;
    next_grid_ = time, grid_ = 0;  // a gap beyond the grid's reach restarts the jerk's history
  }
  if (first) {
    EmitGrid(time, filtered_, 0.0);
  } else if (dt > kGapS && dt <= kMaxBridgedGapS && velocity_known_) {
    const Eigen::Vector3d c = (tip - last_tip_ - velocity_ * dt) / (dt * dt);
    const int pieces = std::min(kMaxPieces, static_cast<int>(std::ceil(dt / 1e-3)));
    const double h = dt / pieces;
    const double a = std::exp(-kOmega * h);
    Eigen::Vector3d from = last_tip_;
    for (int k = 1; k <= pieces; ++k) {
      const double s = h * k;
      const Eigen::Vector3d to =
          k == pieces ? tip : Eigen::Vector3d(last_tip_ + velocity_ * s + c * s * s);
      FilterPiece(t_last_ + h * (k - 1), from, k == pieces ? time : t_last_ + s, to, a);
      from = to;
    }
  } else {
    FilterPiece(t_last_, last_tip_, time, tip, std::exp(-kOmega * dt));
  }
  // The velocity the next gap starts with: over the newest samples spanning ≥ kVelocityBase
  // (a burst's samples microseconds apart would turn a micrometre of sensor noise into m/s).
  history_[history_next_] = {time, tip};
  history_next_ = (history_next_ + 1) % kHistory;
  history_size_ = std::min(history_size_ + 1, kHistory);
  velocity_known_ = false;
  for (int k = 2; k <= history_size_; ++k) {
    const Sample& old = history_[(history_next_ - k + kHistory) % kHistory];
    if (time - old.time >= kVelocityBase) {
      velocity_ = (tip - old.tip) / (time - old.time);
      velocity_known_ = true;
      break;
    }
  }
  ++samples_;
  last_tip_ = tip;
  peak_ = std::max(peak_, force);
  if (overload && !was_overloaded_) ++overloads_;
  was_overloaded_ = overload;
  const double error = std::abs(quantity - task_.target);
  const bool ok = error <= task_.tolerance && force <= task_.force_limit;
  if (ok && !in_window_) in_window_ = true, window_start_ = time;
  if (!ok) in_window_ = false;
  if (!completed_ && in_window_ && time - window_start_ >= task_.hold_s &&
      task_.kind != TaskKind::kPalpate &&  // a palpation completes when the search ends,
      task_.kind != TaskKind::kInsert &&   // a needle when its tip is confirmed in the target,
      task_.kind != TaskKind::kCut) {      // a cut when it covers the pattern (cut.h)
    completed_ = true;
    completion_ = time - t0_;
    error_at_completion_ = error;
  }
  last_quantity_ = quantity;
  t_last_ = time;
}

void TrialRecorder::FilterPiece(double t0, const Eigen::Vector3d& u0, double t1,
                                const Eigen::Vector3d& u1, double decay) {
  // Exact for u moving linearly from u0 to u1: with a = e^(−ω·dt) and slope s = (u1 − u0)/dt,
  // y1 = u1 − s/ω + (y0 − u0 + s/ω)·a.
  const double dt = t1 - t0;
  const Eigen::Vector3d previous = filtered_;
  if (kOmega * dt > 1e-9) {  // a shorter step leaves y unchanged to O(ω·dt), never 0/0
    const Eigen::Vector3d lag = (u1 - u0) / (dt * kOmega);  // s/ω
    filtered_ = u1 - lag + (previous - u0 + lag) * decay;
  }
  EmitGrid(t1, previous, dt);
}

void TrialRecorder::EmitGrid(double t1, const Eigen::Vector3d& previous, double dt) {
  // The grid points up to t1, the filtered tip interpolated linearly over the step dt that ends
  // there. The walk counts its steps, so a time so large that next_grid_ + kGrid == next_grid_
  // cannot spin.
  for (int steps = 0; next_grid_ <= t1 && steps <= kMaxGridSteps; ++steps) {
    const double w = dt > 0 ? 1.0 - (t1 - next_grid_) / dt : 1.0;
    for (int k = 3; k > 0; --k) x_[k] = x_[k - 1];
    x_[0] = previous + w * (filtered_ - previous);
    if (++grid_ >= 4) {
      const Eigen::Vector3d jerk =
          (x_[0] - 3.0 * x_[1] + 3.0 * x_[2] - x_[3]) / (kGrid * kGrid * kGrid);
      jerk2_ += jerk.squaredNorm() * kGrid;
    }
    next_grid_ += kGrid;
  }
}

ScoreParts TimeAndForceParts(const TrialMetrics& m, const TaskSpec& task) {
  auto unit = [](double v) { return std::clamp(v, 0.0, 1.0); };
  ScoreParts p;
  p.efficiency = m.completed ? unit(task.expert_time / std::max(1e-9, m.completion_time)) : 0.0;
  p.force =
      unit(1.0 - m.time_over_force_limit / 1.0) * (m.peak_force > task.force_limit ? 0.5 : 1.0);
  return p;
}

double ScoreButSmoothness(const TrialMetrics& m, const TaskSpec& task) {
  return m.raw_score - 10.0 * ScoreParts::kSmoothnessWeight * ScorePartsOf(m, task).smoothness;
}

ScoreParts ScorePartsOf(const TrialMetrics& m, const TaskSpec& task) {
  auto unit = [](double v) { return std::clamp(v, 0.0, 1.0); };
  ScoreParts p = TimeAndForceParts(m, task);
  p.accuracy = unit(1.0 - m.task_error / (2.0 * task.tolerance));
  p.smoothness = unit(1.0 - std::log10(std::max(1.0, m.rms_jerk / 5.0)) / 2.0);
  return p;
}

void ApplyScoreGates(const ScoreParts& parts, TrialMetrics& m) {
  m.caps = 0;
  m.raw_score = parts.Points();
  m.score = m.raw_score;
  if (!m.completed) m.caps |= kCapNotCompleted, m.score = std::min(m.score, 5.0);
  if (m.time_over_force_limit > 0.5) m.caps |= kCapForceLimit, m.score = std::min(m.score, 4.0);
  if (m.overload_events > 0) m.caps |= kCapOverload, m.score = std::min(m.score, 3.0);
}

Expected<TaskSpec> ApplyTaskSettings(TaskSpec t, const TaskSettings& s) {
  const bool twist = t.kind == TaskKind::kTwist;
  const char* target_name = twist ? "target_deg" : "target_depth_m";
  const char* tolerance_name = twist ? "tolerance_deg" : "tolerance_m";
  const auto bad = [](const char* field, const std::string& why) {
    return Error{ErrorCode::kInvalidArgument, why, field};
  };
  if (t.kind == TaskKind::kPalpate && (s.kind || s.target || s.tolerance))
    return bad(s.tolerance && !s.target ? "tolerance" : "target",
               "the scene's task is a palpation: it has no target or tolerance");
  if (t.kind == TaskKind::kInsert && (s.kind || s.target || s.tolerance))
    return bad(s.tolerance && !s.target ? "tolerance" : "target",
               "the scene's task is a needle insertion: its target is the scene's");
  if (t.kind == TaskKind::kCut && (s.kind || s.target || s.tolerance))
    return bad(s.tolerance && !s.target ? "tolerance" : "target",
               "the scene's task is a cut: its pattern and band are the scene's");
  if (s.kind && *s.kind != t.kind)
    return bad(target_name, std::string("the scene's task is a ") + (twist ? "twist" : "press") +
                                ": give " + target_name + " and " + tolerance_name);
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  // The ranges a trainee can meet on a 3.3 N desktop device: a twist of 5–180° within
  // 0.5–45°, a press of 1–40 mm within 0.2–20 mm.
  const double lo = twist ? 5 * kDeg : 1e-3, hi = twist ? 180 * kDeg : 0.04;
  const double tol_lo = twist ? 0.5 * kDeg : 2e-4, tol_hi = twist ? 45 * kDeg : 0.02;
  if (s.target) {
    if (!(*s.target >= lo && *s.target <= hi))
      return bad(target_name, twist ? "5 to 180 degrees" : "0.001 to 0.04 m");
    t.target = *s.target;
  }
  if (s.tolerance) {
    if (!(*s.tolerance >= tol_lo && *s.tolerance <= tol_hi))
      return bad(tolerance_name, twist ? "0.5 to 45 degrees" : "0.0002 to 0.02 m");
    t.tolerance = *s.tolerance;
  }
  if (s.hold_s) {
    if (!(*s.hold_s >= 0 && *s.hold_s <= 60)) return bad("hold_s", "0 to 60 s");
    t.expert_time = std::max(*s.hold_s, t.expert_time + (*s.hold_s - t.hold_s));
    t.hold_s = *s.hold_s;
  }
  if (s.force_limit) {
    if (!(*s.force_limit >= 0.1 && *s.force_limit <= 20))
      return bad("force_limit_n", "0.1 to 20 N");
    t.force_limit = *s.force_limit;
  }
  if (s.time_limit) {
    if (!(*s.time_limit >= 1 && *s.time_limit <= 1800)) return bad("time_limit_s", "1 to 1800 s");
    t.time_limit = *s.time_limit;
  }
  if (!(t.time_limit > t.hold_s))
    return bad(s.time_limit ? "time_limit_s" : "hold_s",
               "the time limit must exceed the hold (" + std::to_string(t.hold_s) + " s)");
  return t;
}

std::string FigureText(const char* format, double a, double b) {
  char line[200];
  std::snprintf(line, sizeof line, format, a, b);
  return std::string(line);
}

std::vector<std::string> ExplainLosses(const TrialMetrics& m, const TaskSpec& task,
                                       const ScoreParts& p, const std::string& not_completed,
                                       const std::array<std::string, 4>& why) {
  std::vector<std::string> out;
  if (m.caps & kCapOverload)
    out.push_back(
        FigureText("The tissue was overloaded %.0f time(s): score capped at 3", m.overload_events));
  if (m.caps & kCapForceLimit)
    out.push_back(FigureText("%.1f s above the %.1f N force limit: score capped at 4",
                             m.time_over_force_limit, task.force_limit));
  if (m.caps & kCapNotCompleted) out.push_back(not_completed + ": score capped at 5");
  struct Loss {
    double points;
    std::string why;
  };
  std::vector<Loss> losses = {
      {ScoreParts::Lost(ScoreParts::kAccuracyWeight, p.accuracy), why[0]},
      {ScoreParts::Lost(ScoreParts::kEfficiencyWeight, p.efficiency), why[1]},
      {ScoreParts::Lost(ScoreParts::kForceWeight, p.force), why[2]},
      {ScoreParts::Lost(ScoreParts::kSmoothnessWeight, p.smoothness), why[3]},
  };
  std::sort(losses.begin(), losses.end(),
            [](const Loss& a, const Loss& b) { return a.points > b.points; });
  for (const Loss& l : losses)
    if (l.points >= 0.3) out.push_back(l.why + FigureText(": -%.1f points", l.points));
  return out;
}

std::vector<std::string> ExplainScore(const TrialMetrics& m, const TaskSpec& task) {
  if (task.kind == TaskKind::kPalpate) return ExplainPalpation(m, task);
  if (task.kind == TaskKind::kInsert) return ExplainNeedle(m, task);
  if (task.kind == TaskKind::kCut) return ExplainCutTrial(m, task);
  const bool twist = task.kind == TaskKind::kTwist;
  const double unit = twist ? 180 / 3.14159265358979 : 1e3;
  return ExplainLosses(
      m, task, ScorePartsOf(m, task), "The task was not completed (reach the target and hold it)",
      {FigureText(
           twist ? "Accuracy: %.1f deg from the target" : "Accuracy: %.1f mm from the target",
           m.task_error * unit) +
           FigureText(" (tolerance %.1f)", task.tolerance * unit),
       m.completed
           ? FigureText("Time: %.1f s, an expert takes %.1f s", m.completion_time, task.expert_time)
           : std::string("Time: no credit without completing the task"),
       FigureText("Force control: peak %.2f N against a %.1f N limit", m.peak_force,
                  task.force_limit),
       FigureText("Smoothness: jerky motion (RMS jerk %.0f m/s³)", m.rms_jerk)});
}

void TrialRecorder::AddGuidance(double time, double alpha) {
  if (guide_t_ >= 0 && time > guide_t_ && guide_alpha_ > 0) {
    guided_s_ += time - guide_t_;
    guided_alpha_s_ += guide_alpha_ * (time - guide_t_);
  }
  guide_t_ = time;
  guide_alpha_ = std::isfinite(alpha) ? std::clamp(alpha, 0.0, 1.0) : 0.0;
}

TrialMetrics TrialRecorder::Finish() const {
  TrialMetrics m;
  if (samples_ == 0) {
    m.caps = kCapNotCompleted;
    return m;
  }
  m.completed = completed_;
  m.completion_time = completed_ ? completion_ : 0.0;
  m.task_error = completed_ ? error_at_completion_ : std::abs(last_quantity_ - task_.target);
  m.peak_force = peak_;
  m.time_over_force_limit = over_;
  m.path_length = path_;
  m.duration = t_last_ - t0_;
  m.overload_events = overloads_;
  if (m.duration > 0) m.rms_jerk = std::sqrt(jerk2_ / m.duration);
  if (m.duration > 0) m.guided_share = std::min(1.0, guided_s_ / m.duration);
  if (guided_s_ > 0) m.guided_alpha = guided_alpha_s_ / guided_s_;
  ApplyScoreGates(ScorePartsOf(m, task_), m);
  return m;
}

}  // namespace vsurg::scoring
