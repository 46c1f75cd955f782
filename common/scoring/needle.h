// A needle insertion's own metrics (DESIGN.md "Scoring: needle insertion"): the trainee places
// a needle's tip in a target under the skin (a vessel's lumen, a cyst) and confirms it there
// (the device's mark button), without passing through the target's back wall.
//
// Metrics, fed by the simulation, which knows the needle's tract and the target:
//   - depth error: the tip's distance along its tract from the target's middle on that tract
//     (for a vessel, halfway between its walls where the tract crosses them; for a cyst, the
//     nearest point of the tract to its centre), at the confirmation, else the closest it came;
//   - path deviation: how far the tract passes from the target's centre (a cyst) or axis (a
//     vessel), at the same moment: the aim;
//   - punctures: every boundary given way (skin, layers, walls; a tract followed again punctures
//     nothing new); back-wall breaches among them;
//   - lateral strain: the largest of the tract's lateral strain (the tip's distance from its
//     tract over the shaft's length in tissue: the needle levered sideways tears tissue);
//   - the time, peak force and time over the limit, as every task.
// The trial completes when the tip is confirmed inside the target before the time limit.
//
// Score, 0-10, weights: accuracy 0.4 (1 − depth error/(2·tolerance) − deviation/(4·tolerance)),
// efficiency 0.2 (expert time / completion time, when completed), force control 0.2 (as every
// task), tissue care 0.2 (1 − lateral strain/0.3 − ¼ per puncture beyond the ones the final tract
// needed to reach the target). Gates as every task, and one of its own: a back-wall breach caps
// the score at 3 (a through-and-through puncture is the complication the task is about).
//
// Threads: the recorder belongs to the haptic thread; nothing allocates. Units: m, s, N.
#pragma once

#include <string>
#include <vector>

#include "common/scoring/metrics.h"
#include "common/scoring/trial_metrics.h"

namespace vsurg::scoring {

// The tissue care's strain at which it is worth nothing.
inline constexpr double kNeedleStrainLimit = 0.3;

// One sample of a needle in tissue, as the simulation sees it.
struct NeedleSample {
  bool inserted = false;      // the skin punctured, the tip on a tract
  bool in_target = false;     // the tip inside the target
  double strain = 0;          // the tract's lateral strain now
  double depth_error = 0;     // m, |tip − the target's middle| along the tract (inserted only)
  double path_deviation = 0;  // m, the tract's distance from the target's centre or axis
  int needed = 0;             // punctures the tract needs to reach the target (skin … its wall)
};

class NeedleRecorder {
 public:
  void Add(const NeedleSample& s);
  // The trainee confirms the tip in the target (the mark button). The first confirmation made
  // in the target counts; one outside it is counted and does not end the task. False when it
  // was not in the target.
  bool Confirm(double time, const NeedleSample& s);
  // Fills the needle fields of `m` (from the trial recorder: its duration and force figures),
  // completion, and the score for `task`; `punctures` and `breaches` are the model's counts.
  void Complete(TrialMetrics& m, const TaskSpec& task, int punctures, int breaches) const;

  bool confirmed() const { return confirmed_; }
  int wrong_confirmations() const { return wrong_; }
  template <class A>
  void Persist(A& a) {
    a(last_, has_best_, peak_strain_, confirmed_, confirm_time_, at_confirm_, wrong_,
      ever_inserted_);
  }

 private:
  struct Kept {
    double depth_error = 0, path_deviation = 0;
    int needed = 0;
    template <class A>
    void Persist(A& a) {
      a(depth_error, path_deviation, needed);
    }
  };
  Kept last_, at_confirm_;  // the best placement so far, and the confirmed one
  bool has_best_ = false;
  double peak_strain_ = 0;
  bool confirmed_ = false;
  double confirm_time_ = 0;
  int wrong_ = 0;
  bool ever_inserted_ = false;
};

ScoreParts NeedleScoreParts(const TrialMetrics& m, const TaskSpec& task);
// What lowered a needle insertion's score, in the trainee's words (as ExplainScore).
std::vector<std::string> ExplainNeedle(const TrialMetrics& m, const TaskSpec& task);

}  // namespace vsurg::scoring
