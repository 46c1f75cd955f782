// Pattern cutting's metrics (DESIGN.md "Scoring: pattern cutting"): the trainee cuts along a
// marked line or circle (FLS's pattern-cutting drill) with a blade through a thin tissue.
//
// Fed by the cut's own path as it grows (the crack, from the blade model) and by the blade's
// samples:
//   - deviation: the cut's distance from the marked pattern, RMS and maximum over its length (m);
//   - outside: the length of cut farther from the pattern than the band's half width (m);
//   - coverage: the share of the pattern with cut within the band beside it;
//   - depth consistency: the share of the blade's travel along the pattern, once started, made
//     through the tissue (a blade lifted mid-cut and put in again scores lower), and the lifts
//     before the drill was complete;
//   - tissue torn by pulling instead of cutting (the grasping hand's pull past the tissue's failure
//     strain), m;
//   - the time, peak force and time over the force limit, as every task.
// The drill completes when the cut covers 95% of the pattern (and, for a circle, the piece comes
// free) before the time limit.
//
// Score, 0-10: accuracy 0.4 (1 − RMS deviation / band), completeness 0.3 (coverage), efficiency
// 0.15 (expert time / time, when completed), care 0.15 (1 − outside length / pattern length −
// 0.1 per lift − the share of time over the force limit), where the torn length counts as cut
// outside the band.
//
// Units: m, s, N. The recorder does not allocate per sample.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/trial_metrics.h"

namespace vsurg::scoring {

struct CutPattern {
  enum class Kind { kLine, kCircle };
  Kind kind = Kind::kLine;
  double ax = 0, ay = 0, bx = 0, by = 0;  // m, a line's ends
  double cx = 0, cy = 0, radius = 0;      // m, a circle
  double band = 0.002;                    // m, the band's half width either side

  double Length() const;
  // The point at parameter u ∈ [0, 1] along the pattern (a circle from angle 0, anticlockwise).
  void At(double u, double& x, double& y) const;
  // The distance from (x, y) to the pattern, and the parameter of its nearest point.
  double Distance(double x, double y, double* u = nullptr) const;
};

struct CutMetrics {
  double deviation_rms = 0, deviation_max = 0;  // m
  double cut_length = 0, outside_length = 0;    // m
  double coverage = 0;                          // [0, 1]
  double through_share = 0;                     // [0, 1]
  int lifts = 0;
  bool piece_freed = false;
  bool completed = false;
  double completion_time = 0, duration = 0;    // s
  double peak_force = 0, time_over_limit = 0;  // N, s
  double torn_length = 0;                      // m, torn by pulling instead of cut
  double score = 0;                            // 0-10
};

struct CutTask {
  CutPattern pattern;
  double force_limit = 3.0;  // N
  double time_limit = 120;   // s
  double expert_time = 20;   // s
};

class CutRecorder {
 public:
  static constexpr int kBins = 400;  // the pattern's coverage in 400 pieces
  explicit CutRecorder(const CutPattern& p) : p_(p) {}

  // The blade at time t (s), at (x, y), through the tissue or not, pressing with `force` N.
  void AddSample(double t, double x, double y, bool through, double force, double force_limit);
  // The cut grown from (ax, ay) to (bx, by).
  void AddCut(double ax, double ay, double bx, double by);
  void PieceFreed(double t);
  // Tissue torn by pulling (m of edges past the failure strain), not cut.
  void Torn(double length) {
    if (length > 0) torn_ += length;
  }

  CutMetrics Complete(const CutTask& task) const;

 private:
  CutPattern p_;
  std::array<bool, kBins> covered_{};
  double dev2_ = 0, dev_max_ = 0, length_ = 0, outside_ = 0;
  double last_t_ = 0, last_x_ = 0, last_y_ = 0;
  bool has_last_ = false, was_through_ = false, started_ = false;
  double along_ = 0, along_through_ = 0;
  int lifts_ = 0;
  double peak_ = 0, over_ = 0, freed_at_ = -1, complete_at_ = -1, t_ = 0, torn_ = 0;
};

// What lowered a cut's score, in the trainee's words.
std::vector<std::string> ExplainCut(const CutMetrics& m, const CutTask& task);

// A cut as a session's trial (the trial record every task shares, trial_metrics.h): the cut's
// figures into `m` (task_error its RMS deviation, coverage the pattern's share cut, the cut's own
// fields), its completion, and the score in the platform's four parts with the gates every task
// applies: accuracy ½(1 − RMS/band) + ½·coverage, efficiency and force control as every task,
// and the tissue's care in the fourth part's place: 1 − (outside + torn)/pattern length −
// 0.1 per lift. `task` is the session's: its target is the pattern's length (m), its tolerance
// the band's half width.
void CompleteCutTrial(const CutMetrics& cut, const TaskSpec& task, TrialMetrics& m);
ScoreParts CutScoreParts(const TrialMetrics& m, const TaskSpec& task);
std::vector<std::string> ExplainCutTrial(const TrialMetrics& m, const TaskSpec& task);

// Proficiency targets for the drill from the experts' own runs (proficiency.h's ExpertBenchmark,
// mean ± k·SD), on the metrics a cut is judged by: deviation RMS and maximum, outside and torn
// length, lifts, completion time (lower is better) and coverage (higher). An attempt passes when
// it meets every one (non-compensatory).
struct CutTarget {
  std::string metric;
  bool lower_is_better = true;
  double value = 0;
};
struct CutCheck {
  std::string metric;
  double value = 0, target = 0;
  bool met = false;
};
// At least two experts, each completed; else kInvalidArgument naming "experts".
Expected<std::vector<CutTarget>> CutTargetsFromExperts(const std::vector<CutMetrics>& experts,
                                                       double k = 2.0);
std::vector<CutCheck> CheckCut(const CutMetrics& m, const std::vector<CutTarget>& targets);

}  // namespace vsurg::scoring
