#include "common/scoring/palpation.h"

#include <algorithm>
#include <cmath>

namespace vsurg::scoring {

namespace {

constexpr double kRevisitStep = 1e-3;  // m, the tool's move between two coverage visits
constexpr double kFullCoverage = 0.8;  // the share of the surface that earns full thoroughness

double Unit(double v) {
  return std::clamp(v, 0.0, 1.0);
}

}  // namespace

PalpationRecorder::PalpationRecorder(std::vector<Lump> lumps, PalpableSurface surface,
                                     const PalpationSpec& spec)
    : spec_(spec), lumps_(std::move(lumps)), surface_(std::move(surface)) {
  const int n = static_cast<int>(surface_.centroids.size());
  covered_.assign(n, 0);
  for (double a : surface_.areas) total_area_ += a;
  if (n == 0 || !(spec_.cover_radius > 0)) return;
  Eigen::Vector3d lo = surface_.centroids[0], hi = lo;
  for (const Eigen::Vector3d& c : surface_.centroids) lo = lo.cwiseMin(c), hi = hi.cwiseMax(c);
  grid_origin_ = lo;
  for (int k = 0; k < 3; ++k)
    grid_size_[k] = 1 + static_cast<int>((hi[k] - lo[k]) / spec_.cover_radius);
  const auto cell_of = [&](const Eigen::Vector3d& c) {
    int idx[3];
    for (int k = 0; k < 3; ++k)
      idx[k] =
          std::clamp(static_cast<int>((c[k] - lo[k]) / spec_.cover_radius), 0, grid_size_[k] - 1);
    return (idx[2] * grid_size_[1] + idx[1]) * grid_size_[0] + idx[0];
  };
  cell_start_.assign(static_cast<size_t>(grid_size_[0]) * grid_size_[1] * grid_size_[2] + 1, 0);
  for (const Eigen::Vector3d& c : surface_.centroids) ++cell_start_[cell_of(c) + 1];
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(n);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int t = 0; t < n; ++t) cell_items_[fill[cell_of(surface_.centroids[t])]++] = t;
}

void PalpationRecorder::Add(bool contact, const Eigen::Vector3d& point, double force) {
  if (!contact || !point.allFinite() || !std::isfinite(force)) return;
  force_sum_ += force;
  ++contact_samples_;
  if (force < spec_.press_force) return;
  if (visited_ && (point - last_visit_).norm() < kRevisitStep) return;
  visited_ = true;
  last_visit_ = point;
  Cover(point);
}

// Every centroid within the cover radius of `p`: the 27 grid cells around it.
void PalpationRecorder::Cover(const Eigen::Vector3d& p) {
  if (cell_start_.empty()) return;
  const double r = spec_.cover_radius;
  int centre[3];
  for (int k = 0; k < 3; ++k) {
    const double c = std::floor((p[k] - grid_origin_[k]) / r);
    if (!(c >= -1 && c <= grid_size_[k])) return;  // more than a cell outside the surface's box
    centre[k] = static_cast<int>(c);
  }
  for (int z = centre[2] - 1; z <= centre[2] + 1; ++z)
    for (int y = centre[1] - 1; y <= centre[1] + 1; ++y)
      for (int x = centre[0] - 1; x <= centre[0] + 1; ++x) {
        if (x < 0 || y < 0 || z < 0 || x >= grid_size_[0] || y >= grid_size_[1] ||
            z >= grid_size_[2])
          continue;
        const int cell = (z * grid_size_[1] + y) * grid_size_[0] + x;
        for (int i = cell_start_[cell]; i < cell_start_[cell + 1]; ++i) {
          const int t = cell_items_[i];
          if (covered_[t] || (surface_.centroids[t] - p).squaredNorm() > r * r) continue;
          covered_[t] = 1;
          covered_area_ += surface_.areas[t];
        }
      }
}

bool PalpationRecorder::Mark(double time, const Eigen::Vector3d& point) {
  if (marks_ >= kMaxMarks || !point.allFinite() || !std::isfinite(time)) return false;
  mark_[marks_] = point;
  mark_time_[marks_] = time;
  ++marks_;
  return true;
}

// Marks and lumps paired closest first (at most 16 × 16 pairs, no allocation).
int PalpationRecorder::Pair(int* lump_of, double* error_sum) const {
  const int lumps = std::min(static_cast<int>(lumps_.size()), kMaxMarks);
  bool lump_used[kMaxMarks] = {};
  std::fill(lump_of, lump_of + marks_, -1);
  int found = 0;
  *error_sum = 0;
  for (;;) {
    int best_mark = -1, best_lump = -1;
    double best = 0;
    for (int i = 0; i < marks_; ++i) {
      if (lump_of[i] >= 0) continue;
      for (int j = 0; j < lumps; ++j) {
        if (lump_used[j]) continue;
        const double d = (mark_[i] - lumps_[j].surface).norm();
        if (d > lumps_[j].radius + spec_.match_margin) continue;
        if (best_mark < 0 || d < best) best_mark = i, best_lump = j, best = d;
      }
    }
    if (best_mark < 0) return found;
    lump_of[best_mark] = best_lump;
    lump_used[best_lump] = true;
    ++found;
    *error_sum += best;
  }
}

PalpationOutcome PalpationRecorder::Outcome() const {
  int lump_of[kMaxMarks];
  double error_sum = 0;
  Pair(lump_of, &error_sum);
  PalpationOutcome out{lumps_, std::vector<bool>(lumps_.size(), false), {}};
  for (int i = 0; i < marks_; ++i) {
    out.marks.push_back({mark_[i], mark_time_[i], lump_of[i]});
    if (lump_of[i] >= 0) out.found[static_cast<size_t>(lump_of[i])] = true;
  }
  return out;
}

// The pairs, then the score.
void PalpationRecorder::Complete(TrialMetrics& m, const TaskSpec& task) const {
  int lump_of[kMaxMarks];
  double error_sum = 0;
  const int found = Pair(lump_of, &error_sum);
  m.lumps = static_cast<int>(lumps_.size());
  m.lumps_found = found;
  m.false_marks = marks_ - found;
  m.localisation_error = found > 0 ? error_sum / found : 0.0;
  m.coverage = total_area_ > 0 ? std::min(1.0, covered_area_ / total_area_) : 0.0;
  m.mean_force = contact_samples_ > 0 ? force_sum_ / static_cast<double>(contact_samples_) : 0.0;
  m.task_error = m.localisation_error;
  m.completed = m.duration > 0 && m.duration < task.time_limit && m.coverage > 0;
  m.completion_time = m.completed ? m.duration : 0.0;
  ApplyScoreGates(PalpationScoreParts(m, task), m);
}

ScoreParts PalpationScoreParts(const TrialMetrics& m, const TaskSpec& task) {
  ScoreParts p = TimeAndForceParts(m, task);
  constexpr double kMargin = PalpationSpec{}.match_margin;
  if (m.lumps > 0) {
    const double detection = Unit((m.lumps_found - 0.5 * m.false_marks) / m.lumps);
    p.accuracy = Unit(detection - 0.5 * m.localisation_error / kMargin * m.lumps_found / m.lumps);
  } else {
    p.accuracy = Unit(1.0 - 0.5 * m.false_marks);
  }
  p.smoothness = Unit(m.coverage / kFullCoverage);  // thoroughness, in the fourth part's place
  return p;
}

std::vector<std::string> ExplainPalpation(const TrialMetrics& m, const TaskSpec& task) {
  const int missed = m.lumps - m.lumps_found;
  std::string found =
      m.lumps == 0 ? std::string("Detection: there was no lump")
                   : FigureText("Detection: %.0f of %.0f lump(s) found", m.lumps_found, m.lumps);
  if (m.false_marks > 0) found += FigureText(", %.0f false mark(s)", m.false_marks);
  if (m.lumps_found > 0)
    found += FigureText(", marked %.1f mm from the lump", 1e3 * m.localisation_error);
  if (missed > 0 && m.lumps > 0) found += FigureText(" (%.0f missed)", missed);
  return ExplainLosses(
      m, task, PalpationScoreParts(m, task), "The search was not finished within the time limit",
      {found,
       m.completed
           ? FigureText("Time: %.0f s, an expert takes %.0f s", m.completion_time, task.expert_time)
           : std::string("Time: no credit without finishing the search"),
       FigureText("Force control: peak %.2f N against a %.1f N limit", m.peak_force,
                  task.force_limit),
       FigureText("Thoroughness: %.0f%% of the surface examined", 100 * m.coverage)});
}

}  // namespace vsurg::scoring
