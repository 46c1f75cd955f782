#include "common/scoring/needle.h"

#include <algorithm>
#include <cmath>

namespace vsurg::scoring {

namespace {

double Clamp01(double v) {
  return std::clamp(v, 0.0, 1.0);
}

}  // namespace

void NeedleRecorder::Add(const NeedleSample& s) {
  if (!s.inserted) return;
  ever_inserted_ = true;
  if (std::isfinite(s.strain)) peak_strain_ = std::max(peak_strain_, s.strain);
  if (confirmed_ || !std::isfinite(s.depth_error) || !std::isfinite(s.path_deviation)) return;
  // Until a confirmation: the closest the tip came to the target's middle.
  if (!has_best_ || s.depth_error < last_.depth_error)
    last_ = {s.depth_error, s.path_deviation, s.needed}, has_best_ = true;
}

bool NeedleRecorder::Confirm(double time, const NeedleSample& s) {
  if (confirmed_) return false;
  if (!s.inserted || !s.in_target) {
    ++wrong_;
    return false;
  }
  confirmed_ = true;
  confirm_time_ = time;
  at_confirm_ = {s.depth_error, s.path_deviation, s.needed};
  return true;
}

void NeedleRecorder::Complete(TrialMetrics& m, const TaskSpec& task, int punctures,
                              int breaches) const {
  const Kept& k = confirmed_ ? at_confirm_ : last_;
  m.punctures = punctures;
  m.back_wall_breaches = breaches;
  m.lateral_strain = peak_strain_;
  m.depth_error = ever_inserted_ ? k.depth_error : 0.0;
  m.path_deviation = ever_inserted_ ? k.path_deviation : 0.0;
  m.extra_punctures = std::max(0, punctures - k.needed);
  m.task_error = m.depth_error;
  m.completed = confirmed_ && confirm_time_ < task.time_limit;
  m.completion_time = m.completed ? confirm_time_ : 0.0;
  ApplyScoreGates(NeedleScoreParts(m, task), m);
  if (breaches > 0) m.caps |= kCapBackWall, m.score = std::min(m.score, 3.0);
}

ScoreParts NeedleScoreParts(const TrialMetrics& m, const TaskSpec& task) {
  ScoreParts p = TimeAndForceParts(m, task);
  const double tol = task.tolerance > 0 ? task.tolerance : 0.002;
  p.accuracy = m.punctures > 0
                   ? Clamp01(1.0 - m.depth_error / (2 * tol) - m.path_deviation / (4 * tol))
                   : 0.0;  // never in the tissue: nothing placed
  // Tissue care, in the fourth part's place.
  p.smoothness =
      m.punctures > 0
          ? Clamp01(1.0 - m.lateral_strain / kNeedleStrainLimit - 0.25 * m.extra_punctures)
          : 0.0;
  return p;
}

std::vector<std::string> ExplainNeedle(const TrialMetrics& m, const TaskSpec& task) {
  std::vector<std::string> out;
  // What happened first, whatever it cost: where the tip went and what it passed through.
  out.push_back(m.completed ? FigureText("Placed %.1f mm from the target's middle, %.0f "
                                         "puncture(s)",
                                         1e3 * m.depth_error, m.punctures)
                            : FigureText("Not confirmed in the target; the tip came within "
                                         "%.1f mm of its middle, %.0f puncture(s)",
                                         1e3 * m.depth_error, m.punctures));
  if (m.back_wall_breaches > 0)
    out.push_back(FigureText("The needle passed through the target's back wall (%.0f time(s))",
                             m.back_wall_breaches));
  std::vector<std::string> rest = ExplainLosses(
      m, task, NeedleScoreParts(m, task),
      "The tip was not confirmed inside the target within the time limit",
      {FigureText("Placement: %.1f mm from the target's middle, the path %.1f mm off its centre",
                  1e3 * m.depth_error, 1e3 * m.path_deviation),
       m.completed
           ? FigureText("Time: %.0f s, an expert takes %.0f s", m.completion_time, task.expert_time)
           : std::string("Time: no credit without reaching the target"),
       FigureText("Force control: peak %.2f N against a %.1f N limit", m.peak_force,
                  task.force_limit),
       FigureText("Tissue care: lateral strain up to %.0f%%", 100 * m.lateral_strain) +
           (m.extra_punctures > 0
                ? FigureText(", %.0f puncture(s) beyond the path's own", m.extra_punctures)
                : std::string())});
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

}  // namespace vsurg::scoring
