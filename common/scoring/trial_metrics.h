// Automatic trial metrics and the 0–10 proficiency score (DESIGN.md "Scoring").
//
// Fed one sample per haptic update: time, tip position, the task's quantity (twist in rad for a
// twist task, press depth in m for a press task), the force magnitude sent to the device (N,
// after its limits) and whether the tissue was overloaded.
//
// Metrics: completion time (first moment the quantity has been within tolerance of the target,
// under the force limit, for hold_s; measured from the first sample), task error (|quantity −
// target| at completion, or at the end if never completed), peak force, time over the force
// limit, path length of the tip, RMS jerk of the tip (m/s³; the third derivative of the position
// low-passed at 10 Hz, above the band of voluntary movement, so sensor noise does not count, and
// read on a uniform 10 ms grid, so the jitter of a station's sample clock does not either; a gap
// in the samples is bridged by the parabola that leaves the last sample with its velocity, so
// a stalled station or a burst of lost datagrams does not read as a jerky hand either), and
// overload events (each onset counts once). The normalised jerk of Teulings et al. was tried and
// dropped: it assumes one reach, and a trial's holds and approach made it ~10⁴ for everyone.
//
// Score, 0–10, weights: accuracy 0.4 (1 − error/(2·tolerance)), efficiency 0.2 (expert time /
// completion time, 0 if not completed), force control 0.2 (1 − time over limit/1 s, halved if the
// peak exceeded the limit), smoothness 0.2 (1 − log10(RMS jerk / 5 m/s³)/2: a smooth 2-s twist
// with a 0.4-s approach scores 1), each clamped to [0, 1].
// Non-compensatory safety gates, as proficiency-based curricula use: not completed caps the
// score at 5; more than 0.5 s over the force limit caps it at 4; any overload caps it at 3.
//
// Threads: a recorder belongs to the haptic thread; Add never allocates and does bounded work
// (at most 100 pieces of a bridged gap and 129 grid points, whatever the times it is given).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/scoring/metrics.h"

namespace vsurg::scoring {

// kPalpate: search the tissue for hidden lumps and mark them (palpation.h); it has no target or
// tolerance of its own. kInsert: place a needle's tip in a target under the skin (needle.h); its
// target is the target's middle, its tolerance a distance (m). kCut: cut along a marked line or
// circle (cut.h); its target is the pattern, its tolerance the band's half width (m).
enum class TaskKind { kTwist, kPress, kPalpate, kInsert, kCut };

// As scene files and the wire spell it: "twist", "press", "palpate", "insert", "cut".
const char* TaskKindName(TaskKind kind);

// How people read a task's target and tolerance: degrees for a twist, millimetres for a press
// (the spec keeps radians and metres). One place for the dashboard, the catalogue and the station.
struct TaskDisplayUnit {
  double per_si;     // display units per rad or m
  const char* name;  // "deg" or "mm"
};
TaskDisplayUnit DisplayUnitOf(TaskKind kind);

struct TaskSpec {
  TaskKind kind = TaskKind::kTwist;
  double target = 0.785398;      // rad (twist) or m (press)
  double tolerance = 0.0872665;  // same unit
  double hold_s = 2.0;           // s
  double force_limit = 3.0;      // N
  double time_limit = 60.0;      // s
  double expert_time = 5.0;      // s, an expert's completion time (the efficiency reference)
};

// An exercise's own settings of its scene's task (a course's "twist to 60° within 5°, under
// 2 N"): each unset field keeps the scene's value. `kind` is the task the target and tolerance
// are given for (they are in its unit: rad or m); unset when neither is.
struct TaskSettings {
  std::optional<TaskKind> kind;
  std::optional<double> target, tolerance, hold_s, force_limit, time_limit;  // TaskSpec's units
  bool empty() const { return !target && !tolerance && !hold_s && !force_limit && !time_limit; }
};
// `base` (a scene's task) with `s` applied. kInvalidArgument naming the field (the scene file's
// names: target_deg, target_depth_m, tolerance_deg, tolerance_m, hold_s, force_limit_n,
// time_limit_s) when a value is out of range, is for the other kind of task, or leaves the time
// limit no longer than the hold. The expert's completion time moves with the hold (their
// approach takes as long as before).
Expected<TaskSpec> ApplyTaskSettings(TaskSpec base, const TaskSettings& s);

// The score's four parts, each in [0, 1] (the weights and formulas above), from a trial's
// metrics: TrialRecorder::Finish scores with them, ExplainScore says what cost points.
struct ScoreParts {
  // Each part's weight: its share of the 10 points.
  static constexpr double kAccuracyWeight = 0.4, kEfficiencyWeight = 0.2, kForceWeight = 0.2,
                          kSmoothnessWeight = 0.2;
  double accuracy = 0, efficiency = 0, force = 0, smoothness = 0;
  // The score before the gates, 0..10.
  double Points() const {
    return 10.0 * (kAccuracyWeight * accuracy + kEfficiencyWeight * efficiency +
                   kForceWeight * force + kSmoothnessWeight * smoothness);
  }
  // Points a part at `value` falls short of its full share by.
  static double Lost(double weight, double value) { return 10.0 * weight * (1.0 - value); }
};
ScoreParts ScorePartsOf(const TrialMetrics& m, const TaskSpec& task);
// The score before the gates without its smoothness part, 0..8: what a network or a second
// participant can move. Smoothness is read from the samples' stamps, and a loaded host's late
// servo cycles stamp samples closer together than they moved, which reads as jerk; comparisons
// of two real-time runs leave it out.
double ScoreButSmoothness(const TrialMetrics& m, const TaskSpec& task);
// The parts every task scores alike: efficiency and force control (the formulas above); the
// others are left at 0 for the task's own.
ScoreParts TimeAndForceParts(const TrialMetrics& m, const TaskSpec& task);
// The score from its parts, and the gates every task applies (the caps above): sets raw_score,
// score and caps from m's completion, time over the limit and overloads.
void ApplyScoreGates(const ScoreParts& parts, TrialMetrics& m);
// A score's explanation in the trainee's words, every task's shape: the gates that capped it
// (`not_completed`: what completing the task means), then each part that cost at least 0.3
// points, largest first, each with its `why` (accuracy, efficiency, force, the fourth part).
std::vector<std::string> ExplainLosses(const TrialMetrics& m, const TaskSpec& task,
                                       const ScoreParts& parts, const std::string& not_completed,
                                       const std::array<std::string, 4>& why);
// One or two figures in a line of an explanation (printf's format).
std::string FigureText(const char* format, double a, double b = 0);

// What lowered a trial's score, in the trainee's words, largest loss first: the gates that
// capped it, then each part that cost at least 0.3 points (with the figure behind it). Empty
// when nothing did. For the station's end-of-trial summary and the dashboard.
std::vector<std::string> ExplainScore(const TrialMetrics& m, const TaskSpec& task);

class TrialRecorder {
 public:
  explicit TrialRecorder(const TaskSpec& task) : task_(task) {}

  void Add(double time, const Eigen::Vector3d& tip, double quantity, double force, bool overload);
  // Four-handed training: the instructor's dominance α at `time` (0: the trainee alone), held
  // until the next call; gives TrialMetrics::guided_share and guided_alpha.
  void AddGuidance(double time, double alpha);
  TrialMetrics Finish() const;
  const TaskSpec& task() const { return task_; }
  // The recorder's state (common/core/state_archive.h): a session moved to another node goes on
  // recording where it was. The task is not part of it (the receiver builds it from the scene).
  // Every member below but task_ is listed.
  template <class A>
  void Persist(A& a) {
    a(samples_, t0_, t_last_, last_quantity_, filtered_, x_, grid_, next_grid_, last_tip_, history_,
      history_size_, history_next_, velocity_, velocity_known_, jerk2_, path_, peak_, over_,
      was_overloaded_, overloads_, in_window_, window_start_, completed_, completion_,
      error_at_completion_, guide_t_, guide_alpha_, guided_s_, guided_alpha_s_);
  }

 private:
  // Low-passes a piece of path along which the tip moves linearly from u0 (t0) to u1 (t1);
  // decay = e^(−ω·(t1 − t0)).
  void FilterPiece(double t0, const Eigen::Vector3d& u0, double t1, const Eigen::Vector3d& u1,
                   double decay);
  void EmitGrid(double t1, const Eigen::Vector3d& previous, double dt);
  TaskSpec task_;
  int samples_ = 0;
  double t0_ = 0, t_last_ = 0;
  double last_quantity_ = 0;
  Eigen::Vector3d filtered_ = Eigen::Vector3d::Zero();  // tip low-passed at 10 Hz
  // The filtered tip resampled on a uniform 100 Hz grid (linear interpolation between samples),
  // newest first: the jerk's third difference needs even spacing, and stylus samples stamped by
  // a station's clock are not (a late cycle, then a quick one).
  // Zeroed: Eigen leaves a vector uninitialised, and this state is saved for migration (a fresh
  // recorder's bytes must be the same every time, and garbage could read as NaN and be refused).
  Eigen::Vector3d x_[4] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                           Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  int grid_ = 0;          // grid points emitted
  double next_grid_ = 0;  // s, the next grid time
  Eigen::Vector3d last_tip_ = Eigen::Vector3d::Zero();
  // The newest samples, for the velocity a gap's parabola leaves the last one with.
  struct Sample {
    double time = 0;
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();
    template <class A>
    void Persist(A& a) {
      a(time, tip);
    }
  };
  static constexpr int kHistory = 32;
  Sample history_[kHistory];
  int history_size_ = 0, history_next_ = 0;
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();  // m/s, at the last sample
  bool velocity_known_ = false;
  double jerk2_ = 0;  // ∫|j|² dt
  double path_ = 0;
  double peak_ = 0;
  double over_ = 0;
  bool was_overloaded_ = false;
  int overloads_ = 0;
  bool in_window_ = false;
  double window_start_ = 0;
  bool completed_ = false;
  double completion_ = 0;
  double error_at_completion_ = 0;
  double guide_t_ = -1, guide_alpha_ = 0;     // the last AddGuidance (−1: none yet)
  double guided_s_ = 0, guided_alpha_s_ = 0;  // s with α > 0, and ∫α dt
};

}  // namespace vsurg::scoring
