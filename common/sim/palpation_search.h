// Scripted palpation: a hand that searches a tissue for lumps the way an examiner does, closed
// on the forces it feels (the palpation's scripted trainees; tests, demos and the expert
// benchmarks). It presses spot after spot of the surface the support leaves free, each to the
// same depth along the surface's normal, and reads the force it feels there (the force
// along the normal, averaged over the hold); then it compares each spot with the tissue around
// it (the healthy tissue's smooth trend: a quadratic in the surface's tangent plane, fitted to
// the spots between `near` and `far` of it, none nearer the rim than `near`; a spot must stand
// out again against the trend fitted without the spots that stood out; a spot nearer the
// rim than `edge` is not judged, as the tissue softens steeply there) and marks the spots that
// stand out by more than its threshold, a lump's place taken as the excess-weighted centre of the
// spots around the peak. It never reads the scene's inclusions: what it knows it felt.
//
// Styles: `expert` (a dense pattern, 6 mm apart, 6 mm deep, the whole surface: the vertical-strip
// search of a clinical breast examination at a firm pressure, marking a spot 3% harder than its
// surroundings), `novice` (a sparse pattern, 15 mm apart, 2 mm deep and quick, leaving out the
// outer 2 cm, marking only what is 8% harder: the common errors of a light, incomplete search
// that calls only an obvious lump). The scripted trainees every exercise has (TraineeStyle):
// `good` is the expert; `hesitant` covers the surface as densely but slowly and timidly (8 mm
// apart, 3 mm deep, pressing and holding twice as long, moving at half the speed) and marks only
// what is 6% harder; `rough` presses hard and fast (26 mm deep, 12 mm apart, in 60 ms) and marks
// whatever is 1.5% harder: over the force limit, with false marks.
//
// Units: m, s, N.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/haptics/types.h"

namespace vsurg::sim {

struct SearchStyle {
  double spacing = 0.006;            // m between the spots pressed
  double depth = 0.006;              // m each press goes under the surface
  double lift = 0.006;               // m above the surface between presses
  double press_s = 0.12;             // s down (and up again)
  double hold_s = 0.08;              // s held at depth, the force read over its second half
  double speed = 0.12;               // m/s moving between spots
  double near = 0.010, far = 0.024;  // m: the spots the healthy trend is fitted to
  double edge = 0.025;               // m from the rim: nearer spots are not judged (RimDistance)
  double skip = 0;                   // m from the rim: nearer spots are not even pressed
  double threshold = 0.03;           // relative excess of force over the trend that marks
  int max_marks = 3;
};
SearchStyle ExpertSearch();
SearchStyle NoviceSearch();
SearchStyle HesitantSearch();
SearchStyle RoughSearch();
// By name: good (= expert), hesitant, rough, expert or novice; the error names `field`.
Expected<SearchStyle> SearchStyleByName(const std::string& name, const std::string& field);
inline constexpr const char* kSearchStyleNames = "good, hesitant, rough, expert or novice";

class Simulation;
class PalpationSearch;

// Runs `search` through `simulation` to its end, closed on its answers: one sample per
// millisecond of the search's own time, the quasi-static contact stepped after every fourth.
// `each` (optional) sees every sample and its answer. At most 10⁷ samples (2.8 h).
void SearchThrough(Simulation& simulation, PalpationSearch& search,
                   const std::function<void(const haptics::StylusSample&,
                                            const haptics::ForceCommand&)>& each = {});

class PalpationSearch {
 public:
  // `rest`: the tissue's surface at rest; `held`: its vertices the support holds (never pressed).
  static Expected<PalpationSearch> Create(const geometry::TriMesh& rest,
                                          const std::vector<int>& held, const SearchStyle& style);
  // The sample at time `t` (s from the search's start), given the answer to the previous one
  // (null for the first). The buttons carry haptics::kButtonMark while a mark is placed.
  haptics::StylusSample Next(double t, const haptics::ForceCommand* last);
  bool done() const { return phase_ == Phase::kDone; }
  // The spots pressed, the force each felt (N) and its excess over the healthy trend.
  const std::vector<geometry::Vec3>& spots() const { return spot_; }
  const std::vector<double>& felt() const { return felt_; }
  const std::vector<double>& excess() const { return excess_; }
  const std::vector<geometry::Vec3>& marks() const { return marks_; }
  // The time the whole search takes (s), known at Create for the pressing and after it for the
  // marks.
  double planned_s() const { return plan_.empty() ? 0 : plan_.back().t1; }

 private:
  enum class Phase { kPressing, kMarking, kDone };
  struct Move {
    double t0, t1;
    geometry::Vec3 from, to;
    uint32_t buttons;
    int read_spot;  // the spot whose force this move reads (−1: none)
  };
  PalpationSearch() = default;
  void PlanMove(const geometry::Vec3& to, double duration, uint32_t buttons = 0, int read = -1);
  void PlanPress(const geometry::Vec3& p, const geometry::Vec3& n, double depth, int read,
                 uint32_t buttons);
  void Analyse();
  double Excess(size_t i, const std::vector<uint8_t>& healthy) const;
  void MarkPeaks(const std::vector<uint8_t>& stands_out);
  void ReadForce(const Move& m, double t, const haptics::ForceCommand& c);
  SearchStyle style_;
  std::vector<geometry::Vec3> spot_, normal_;
  std::vector<double> rim_;  // m, each spot's distance from the palpable rim
  std::vector<double> felt_, felt_sum_, excess_;
  std::vector<int> felt_count_;
  std::vector<geometry::Vec3> marks_;
  std::vector<Move> plan_;
  size_t current_ = 0;
  geometry::Vec3 at_ = geometry::Vec3::Zero();
  Phase phase_ = Phase::kPressing;
};

}  // namespace vsurg::sim
