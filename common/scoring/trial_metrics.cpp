#include "common/scoring/trial_metrics.h"

#include <algorithm>
#include <cmath>

namespace vsurg::scoring {

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
  // The filter is exact for a tip moving linearly from the last sample to this one (first-order
  // hold): with a = e^(−ω·dt) and slope s = (u₁ − u₀)/dt, y₁ = u₁ − s/ω + (y₀ − u₀ + s/ω)·a.
  // Holding the new tip over the whole step instead (zero-order hold) made the filtered path
  // depend on how evenly the samples arrived: a loaded host's late cycles and catch-up bursts
  // read as jerk (19 m/s³ against 0.05 for the same movement delivered evenly).
  constexpr double kGrid = 0.01;                            // s
  constexpr double kOmega = 2.0 * 3.14159265358979 * 10.0;  // rad/s
  const Eigen::Vector3d previous = filtered_;
  if (samples_ == 0) {
    filtered_ = tip;
  } else if (kOmega * dt > 1e-9) {  // a shorter step leaves y unchanged to O(ω·dt), never 0/0
    const Eigen::Vector3d lag = (tip - last_tip_) / (dt * kOmega);  // s/ω
    filtered_ = tip - lag + (previous - last_tip_ + lag) * std::exp(-kOmega * dt);
  }
  // Bounded work per sample whatever the clock does: a gap longer than kMaxGridSteps grid
  // points restarts the grid at this sample (the jerk's history restarts with it), and the walk
  // counts its steps, so a time so large that next_grid_ + kGrid == next_grid_ cannot spin.
  constexpr int kMaxGridSteps = 128;
  if (samples_ == 0 || time - next_grid_ > kMaxGridSteps * kGrid) next_grid_ = time, grid_ = 0;
  for (int steps = 0; next_grid_ <= time && steps <= kMaxGridSteps; ++steps) {
    const double w = dt > 0 ? 1.0 - (time - next_grid_) / dt : 1.0;
    for (int k = 3; k > 0; --k) x_[k] = x_[k - 1];
    x_[0] = previous + w * (filtered_ - previous);
    if (++grid_ >= 4) {
      const Eigen::Vector3d jerk =
          (x_[0] - 3.0 * x_[1] + 3.0 * x_[2] - x_[3]) / (kGrid * kGrid * kGrid);
      jerk2_ += jerk.squaredNorm() * kGrid;
    }
    next_grid_ += kGrid;
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
  if (!completed_ && in_window_ && time - window_start_ >= task_.hold_s) {
    completed_ = true;
    completion_ = time - t0_;
    error_at_completion_ = error;
  }
  last_quantity_ = quantity;
  t_last_ = time;
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
  auto unit = [](double v) { return std::clamp(v, 0.0, 1.0); };
  const double accuracy = unit(1.0 - m.task_error / (2.0 * task_.tolerance));
  const double efficiency =
      completed_ ? unit(task_.expert_time / std::max(1e-9, m.completion_time)) : 0.0;
  const double force =
      unit(1.0 - m.time_over_force_limit / 1.0) * (m.peak_force > task_.force_limit ? 0.5 : 1.0);
  const double smooth = unit(1.0 - std::log10(std::max(1.0, m.rms_jerk / 5.0)) / 2.0);
  m.raw_score = 10.0 * (0.4 * accuracy + 0.2 * efficiency + 0.2 * force + 0.2 * smooth);
  m.score = m.raw_score;
  if (!completed_) m.caps |= kCapNotCompleted, m.score = std::min(m.score, 5.0);
  if (m.time_over_force_limit > 0.5) m.caps |= kCapForceLimit, m.score = std::min(m.score, 4.0);
  if (m.overload_events > 0) m.caps |= kCapOverload, m.score = std::min(m.score, 3.0);
  return m;
}

}  // namespace vsurg::scoring
