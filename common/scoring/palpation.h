// A palpation trial's own metrics (DESIGN.md "Scoring: palpation"): the trainee searches a
// tissue for hidden lumps and marks each place they find one (the device's mark button pressed
// while the tool is on the surface). Possibly several lumps, possibly none.
//
// Metrics, from the marks, the lumps and the presses:
//   - found, missed, false marks: marks and lumps are paired closest first, each used once; a
//     pair counts when the mark lies within the lump's radius plus `match_margin` of the surface
//     point above the lump (the nearest point of the palpable surface to its centre), as an
//     examiner's "here" is judged on the skin, not at the lump's depth;
//   - localisation error: the mean distance from each found lump's surface point to its mark;
//   - coverage: the share of the palpable surface examined, a surface triangle counting once its
//     centroid has been within `cover_radius` (the pad of a fingertip) of a point pressed with at
//     least `press_force`;
//   - mean force: over the samples in contact; the peak and the time over the force limit are the
//     trial recorder's own (trial_metrics.h).
// The trial completes when the trainee ends the search before the time limit, having pressed
// somewhere (coverage > 0).
//
// Score, 0-10, weights: detection and localisation 0.4 (found − ½·false marks over the lumps,
// clamped to [0, 1], then less half of the mean error over the margin; with no lump, 1 less ½
// per false mark), efficiency 0.2 (expert time / duration, when completed), force control 0.2
// (as every task), thoroughness 0.2 (coverage / 0.8). Gates as every task: not completed caps at
// 5, more than 0.5 s over the force limit at 4, an overload at 3.
//
// Threads: the recorder belongs to the haptic thread; Add, Mark and Complete never allocate and
// do bounded work (Add visits the triangles of at most 27 grid cells, and only after the tool has
// moved a millimetre since its last visit).
//
// Units: m, N, s.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/scoring/metrics.h"
#include "common/scoring/trial_metrics.h"

namespace vsurg::scoring {

// A lump as scoring sees it: where it is and the surface point above it.
struct Lump {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();   // m
  double radius = 0;                                  // m
  Eigen::Vector3d surface = Eigen::Vector3d::Zero();  // m, the palpable surface's nearest point
};

// A palpation's outcome as the trainee sees it afterwards (the station's summary draws it over the
// tissue): the lumps that were hidden, each found or not, and the marks, each with the lump it
// found (-1: a false mark).
struct PalpationOutcome {
  struct Placed {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m
    double time = 0;                                     // s into the trial
    int lump = -1;
  };
  std::vector<Lump> lumps;
  std::vector<bool> found;  // per lump
  std::vector<Placed> marks;
};

struct PalpationSpec {
  double match_margin = 0.005;  // m, beyond the lump's radius
  double press_force = 0.3;     // N, a press this firm examines the surface under it
  double cover_radius = 0.006;  // m, the surface one press examines
};

// The palpable surface as scoring sees it: its triangles' centroids and areas.
struct PalpableSurface {
  std::vector<Eigen::Vector3d> centroids;  // m
  std::vector<double> areas;               // m²
};

class PalpationRecorder {
 public:
  static constexpr int kMaxMarks = 16;

  PalpationRecorder() = default;
  PalpationRecorder(std::vector<Lump> lumps, PalpableSurface surface, const PalpationSpec& spec);

  // One haptic sample: whether the tool is in contact, where (the proxy on the surface) and the
  // force on the tissue (N).
  void Add(bool contact, const Eigen::Vector3d& point, double force);
  // A mark at a surface point; false when the trial holds kMaxMarks already (the mark is not
  // kept) or the point is not finite.
  bool Mark(double time, const Eigen::Vector3d& point);
  // Fills the palpation fields of `m` (from the trial recorder: its duration, force figures and
  // gates) and scores it for `task`.
  void Complete(TrialMetrics& m, const TaskSpec& task) const;

  int marks() const { return marks_; }
  const Eigen::Vector3d& mark(int i) const { return mark_[i]; }
  double mark_time(int i) const { return mark_time_[i]; }
  const std::vector<Lump>& lumps() const { return lumps_; }
  // Which lump each mark found (closest first, each used once; -1: none), into `lump_of` (at
  // least marks() long); returns how many were found and the sum of their distances (m).
  int Pair(int* lump_of, double* error_sum) const;
  PalpationOutcome Outcome() const;

  // The state a session moved to another node goes on from (state_archive.h); the lumps, the
  // surface and the spec are rebuilt from the scene.
  template <class A>
  void Persist(A& a) {
    a(mark_, mark_time_, marks_, covered_, covered_area_, last_visit_, visited_, force_sum_,
      contact_samples_);
  }

 private:
  void Cover(const Eigen::Vector3d& p);
  PalpationSpec spec_;
  std::vector<Lump> lumps_;
  PalpableSurface surface_;
  double total_area_ = 0;
  // A uniform grid of the centroids, cell size cover_radius: cell_start_[c]..cell_start_[c+1]
  // index cell_items_.
  Eigen::Vector3d grid_origin_ = Eigen::Vector3d::Zero();
  std::array<int, 3> grid_size_{0, 0, 0};
  std::vector<int> cell_start_, cell_items_;

  // Zeroed (Eigen leaves a vector uninitialised; this state is saved for migration).
  Eigen::Vector3d mark_[kMaxMarks] = {
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero()};
  double mark_time_[kMaxMarks] = {};
  int marks_ = 0;
  std::vector<uint8_t> covered_;
  double covered_area_ = 0;
  Eigen::Vector3d last_visit_ = Eigen::Vector3d::Zero();
  bool visited_ = false;
  double force_sum_ = 0;
  int64_t contact_samples_ = 0;
};

// The score's parts for a palpation (the weights above), each in [0, 1].
ScoreParts PalpationScoreParts(const TrialMetrics& m, const TaskSpec& task);
// What lowered a palpation's score, in the trainee's words (as ExplainScore).
std::vector<std::string> ExplainPalpation(const TrialMetrics& m, const TaskSpec& task);

}  // namespace vsurg::scoring
