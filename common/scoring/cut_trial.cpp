// A cut as a session's trial (cut.h): the cut's figures in the trial record every task shares,
// scored in the platform's four parts.
#include <algorithm>

#include "common/scoring/cut.h"

namespace vsurg::scoring {

ScoreParts CutScoreParts(const TrialMetrics& m, const TaskSpec& task) {
  ScoreParts p = TimeAndForceParts(m, task);
  const double band = task.tolerance > 0 ? task.tolerance : 0.002;
  const double length = std::max(task.target, 1e-3);
  const bool cut = m.coverage > 0;  // nothing cut: nothing to be accurate about
  p.accuracy = cut ? 0.5 * std::clamp(1 - m.task_error / band, 0.0, 1.0) +
                         0.5 * std::clamp(m.coverage, 0.0, 1.0)
                   : 0.0;
  p.smoothness =
      cut ? std::clamp(1 - (m.cut_outside + m.torn_length) / length - 0.1 * m.cut_lifts, 0.0, 1.0)
          : 0.0;
  return p;
}

void CompleteCutTrial(const CutMetrics& cut, const TaskSpec& task, TrialMetrics& m) {
  m.task_error = cut.deviation_rms;
  m.coverage = cut.coverage;
  m.cut_deviation_max = cut.deviation_max;
  m.cut_outside = cut.outside_length;
  m.torn_length = cut.torn_length;
  m.cut_lifts = cut.lifts;
  m.completed = cut.completed;
  m.completion_time = cut.completion_time;
  ApplyScoreGates(CutScoreParts(m, task), m);
}

std::vector<std::string> ExplainCutTrial(const TrialMetrics& m, const TaskSpec& task) {
  return ExplainLosses(m, task, CutScoreParts(m, task),
                       "The pattern was not cut out (cut along the whole line within the band)",
                       {FigureText("Accuracy: %.1f mm RMS from the line", m.task_error * 1e3) +
                            FigureText(", %.0f%% of it cut", 100 * m.coverage) +
                            FigureText(" (band ±%.1f mm)", task.tolerance * 1e3),
                        m.completed ? FigureText("Time: %.1f s, an expert takes %.1f s",
                                                 m.completion_time, task.expert_time)
                                    : std::string("Time: no credit without completing the cut"),
                        FigureText("Force control: peak %.2f N against a %.1f N limit",
                                   m.peak_force, task.force_limit),
                        FigureText("Care: %.1f mm cut outside the band", m.cut_outside * 1e3) +
                            FigureText(", %.1f mm torn", m.torn_length * 1e3) +
                            FigureText(", %.0f lifts of the blade", m.cut_lifts)});
}

}  // namespace vsurg::scoring
