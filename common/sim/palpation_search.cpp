#include "common/sim/palpation_search.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "common/sim/palpation_case.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim {

using geometry::Vec3;

SearchStyle ExpertSearch() {
  return {};
}

SearchStyle NoviceSearch() {
  SearchStyle s;
  s.spacing = 0.015;
  s.depth = 0.002;
  s.press_s = 0.08;
  s.hold_s = 0.05;
  s.speed = 0.2;
  s.near = 0.014;
  s.far = 0.04;
  s.skip = 0.02;
  s.threshold = 0.08;
  return s;
}

SearchStyle HesitantSearch() {
  SearchStyle s;
  s.depth = 0.003;
  s.press_s = 0.25;
  s.hold_s = 0.15;
  s.speed = 0.06;
  s.threshold = 0.06;
  return s;
}

SearchStyle RoughSearch() {
  SearchStyle s;
  s.spacing = 0.012;
  s.depth = 0.026;
  s.press_s = 0.06;
  s.hold_s = 0.04;
  s.speed = 0.3;
  s.near = 0.012;
  s.far = 0.03;
  s.threshold = 0.01;
  s.max_marks = 4;
  return s;
}

void SearchThrough(
    Simulation& simulation, PalpationSearch& search,
    const std::function<void(const haptics::StylusSample&, const haptics::ForceCommand&)>& each) {
  haptics::ForceCommand c;
  for (int i = 0; !search.done() && i < 10'000'000; ++i) {
    const haptics::StylusSample s = search.Next(i * 1e-3, i == 0 ? nullptr : &c);
    c = simulation.OnStylus(s);
    if (each) each(s, c);
    if (i % 4 == 0) simulation.StepDeformation();
  }
}

Expected<SearchStyle> SearchStyleByName(const std::string& name, const std::string& field) {
  if (name == "good" || name == "expert") return ExpertSearch();
  if (name == "hesitant") return HesitantSearch();
  if (name == "rough") return RoughSearch();
  if (name == "novice") return NoviceSearch();
  return InvalidArgument(field, "'" + name + "' is not a search style: " + kSearchStyleNames);
}

namespace {

// The spots: the corners of the palpable surface's triangles (`surface`, sim::PalpableTriangles)
// farther than `skip` from its rim (`rim`, sim::RimDistance), in vertical strips `spacing` wide,
// each strip walked the other way from the last, no two closer than 0.9 spacing.
std::vector<int> ChooseSpots(const geometry::TriMesh& rest, const std::vector<int>& surface,
                             const std::vector<double>& rim, double spacing, double skip) {
  // A corner of the rim (RimDistance 0): a press there slides off, and no examiner presses there.
  std::vector<uint8_t> palpable(rest.VertexCount(), 0);
  for (int t : surface)
    for (int v : rest.triangles[t]) palpable[v] = rim[v] > std::max(0.0, skip - 1e-9);
  std::vector<int> order;
  for (int v = 0; v < rest.VertexCount(); ++v)
    if (palpable[v]) order.push_back(v);
  const auto strip = [&](int v) {
    return static_cast<int>(std::floor(rest.positions[v].x() / spacing));
  };
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const int sa = strip(a), sb = strip(b);
    if (sa != sb) return sa < sb;
    const double ya = rest.positions[a].y(), yb = rest.positions[b].y();
    return (sa % 2 == 0) ? ya < yb : ya > yb;
  });
  std::vector<int> spots;
  for (int v : order) {
    bool apart = true;
    for (int s : spots)
      if ((rest.positions[s] - rest.positions[v]).norm() < 0.9 * spacing) apart = false;
    if (apart) spots.push_back(v);
  }
  return spots;
}

}  // namespace

Expected<PalpationSearch> PalpationSearch::Create(const geometry::TriMesh& rest,
                                                  const std::vector<int>& held,
                                                  const SearchStyle& style) {
  if (!(style.spacing > 0 && style.depth > 0 && style.speed > 0 && style.press_s > 0 &&
        style.hold_s > 0 && style.far > style.near))
    return Error{ErrorCode::kInvalidArgument, "a search style needs positive lengths and times",
                 "style"};
  geometry::TriMesh mesh = rest;
  geometry::ComputeVertexNormals(mesh);
  PalpationSearch s;
  s.style_ = style;
  const std::vector<int> surface = PalpableTriangles(mesh, held);
  const std::vector<double> rim = RimDistance(mesh, surface);
  const std::vector<int> spots = ChooseSpots(mesh, surface, rim, style.spacing, style.skip);
  if (spots.empty())
    return Error{ErrorCode::kInvalidArgument, "no surface to search from above", "rest"};
  for (int v : spots) {
    s.spot_.push_back(mesh.positions[v]);
    s.normal_.push_back(mesh.normals[v]);
    s.rim_.push_back(rim[v]);
  }
  const size_t n = spots.size();
  s.felt_.assign(n, 0);
  s.felt_sum_.assign(n, 0);
  s.felt_count_.assign(n, 0);
  s.excess_.assign(n, 0);
  s.at_ = s.spot_[0] + 2 * style.lift * s.normal_[0];
  s.plan_.push_back({0, 0.2, s.at_, s.at_, 0, -1});  // a moment's rest before the first press
  for (size_t i = 0; i < n; ++i)
    s.PlanPress(s.spot_[i], s.normal_[i], style.depth, static_cast<int>(i), 0);
  return s;
}

void PalpationSearch::PlanMove(const Vec3& to, double duration, uint32_t buttons, int read) {
  const double t0 = plan_.empty() ? 0.0 : plan_.back().t1;
  plan_.push_back({t0, t0 + duration, at_, to, buttons, read});
  at_ = to;
}

// Over the spot at the lift, down to the depth, held, up again.
void PalpationSearch::PlanPress(const Vec3& p, const Vec3& n, double depth, int read,
                                uint32_t buttons) {
  const Vec3 above = p + style_.lift * n;
  PlanMove(above, std::max(0.02, (above - at_).norm() / style_.speed));
  PlanMove(p - depth * n, style_.press_s);
  PlanMove(p - depth * n, style_.hold_s, buttons, read);
  PlanMove(above, style_.press_s);
}

haptics::StylusSample PalpationSearch::Next(double t, const haptics::ForceCommand* last) {
  if (last && current_ < plan_.size()) ReadForce(plan_[current_], t, *last);
  while (current_ < plan_.size() && t > plan_[current_].t1) ++current_;
  if (current_ >= plan_.size() && phase_ == Phase::kPressing) {
    Analyse();
    phase_ = Phase::kMarking;
  }
  if (current_ >= plan_.size()) phase_ = Phase::kDone;
  haptics::StylusSample s;
  s.time = t;
  if (phase_ == Phase::kDone) {
    s.position = plan_.back().to;
    return s;
  }
  const Move& m = plan_[current_];
  const double u = std::clamp((t - m.t0) / std::max(1e-9, m.t1 - m.t0), 0.0, 1.0);
  s.position = m.from + MinJerk(u) * (m.to - m.from);
  s.buttons = m.buttons;
  return s;
}

// The force along the spot's normal over the hold's second half.
void PalpationSearch::ReadForce(const Move& m, double t, const haptics::ForceCommand& c) {
  if (m.read_spot < 0 || t < 0.5 * (m.t0 + m.t1) || !c.force.allFinite()) return;
  felt_sum_[m.read_spot] += c.force.dot(normal_[m.read_spot]);
  ++felt_count_[m.read_spot];
}

// Spot i's excess over the healthy trend around it (0 where it is not judged), the trend fitted
// to the spots between `near` and `far` of it (away from the rim) that `healthy` allows.
double PalpationSearch::Excess(size_t i, const std::vector<uint8_t>& healthy) const {
  const size_t n = spot_.size();
  const Vec3 t1 = geometry::AnyPerpendicular(normal_[i]), t2 = normal_[i].cross(t1);
  std::vector<Eigen::Matrix<double, 6, 1>> rows;
  std::vector<double> values;
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();
  for (size_t j = 0; j < n; ++j) {
    const Vec3 d = spot_[j] - spot_[i];
    const double r = d.norm();
    if (r < style_.near || r > style_.far || felt_count_[j] == 0 || rim_[j] < style_.near ||
        !healthy[j])
      continue;
    const double u = d.dot(t1), v = d.dot(t2);
    rows.push_back((Eigen::Matrix<double, 6, 1>() << 1, u, v, u * u, u * v, v * v).finished());
    values.push_back(felt_[j]);
    offset += Eigen::Vector2d(u, v);
  }
  // At the search's edge the trend is extrapolated from one side: not judged.
  if (rim_[i] < style_.edge || rows.empty() || offset.norm() / rows.size() > 0.3 * style_.far)
    return 0;
  double trend = 0;
  if (rows.size() >= 12) {
    Eigen::MatrixXd a(rows.size(), 6);
    Eigen::VectorXd b(rows.size());
    for (size_t k = 0; k < rows.size(); ++k) a.row(k) = rows[k].transpose(), b[k] = values[k];
    trend = a.colPivHouseholderQr().solve(b)[0];
  } else {
    for (double v : values) trend += v / values.size();
  }
  return trend > 1e-6 && felt_count_[i] ? felt_[i] / trend - 1 : 0;
}

// Each spot against the healthy trend around it, twice: the second time without the spots that
// stood out the first. A strong lump bends the trend fitted around it, and the tissue 2 cm away
// then reads as standing out too; a spot must stand out both times to be marked. The first
// pass's excess places the marks (the second's, with the lump's spots out of every trend, spreads
// a lump's excess wider and placed the marks 1–2 mm farther off).
void PalpationSearch::Analyse() {
  const size_t n = spot_.size();
  for (size_t i = 0; i < n; ++i) felt_[i] = felt_count_[i] ? felt_sum_[i] / felt_count_[i] : 0;
  std::vector<uint8_t> healthy(n, 1);
  for (size_t i = 0; i < n; ++i) excess_[i] = Excess(i, healthy);
  for (size_t i = 0; i < n; ++i) healthy[i] = excess_[i] <= style_.threshold;
  std::vector<uint8_t> stands_out(n, 0);
  for (size_t i = 0; i < n; ++i)
    stands_out[i] = excess_[i] > style_.threshold && Excess(i, healthy) > style_.threshold;
  MarkPeaks(stands_out);
}

// The peaks that stand out by more than the threshold, strongest first, each marked at the
// excess-weighted centre of the spots around it.
void PalpationSearch::MarkPeaks(const std::vector<uint8_t>& stands_out) {
  const size_t n = spot_.size();
  std::vector<size_t> peaks(n);
  for (size_t i = 0; i < n; ++i) peaks[i] = i;
  std::sort(peaks.begin(), peaks.end(),
            [&](size_t a, size_t b) { return excess_[a] > excess_[b]; });
  std::vector<size_t> chosen;
  for (size_t i : peaks) {
    if (!(excess_[i] > style_.threshold) || static_cast<int>(chosen.size()) >= style_.max_marks)
      break;
    if (!stands_out[i]) continue;
    // A peak, not a lump's shoulder: nothing around it stands out more, and it is apart from
    // the peaks already marked.
    const double around = std::max(style_.near, 1.6 * style_.spacing);
    bool peak = true;
    for (size_t j = 0; j < n && peak; ++j)
      peak = !((spot_[j] - spot_[i]).norm() <= around && excess_[j] > excess_[i]);
    for (size_t c : chosen) peak = peak && (spot_[c] - spot_[i]).norm() > around;
    if (!peak) continue;
    chosen.push_back(i);
    Vec3 centre = Vec3::Zero();
    double weight = 0;
    for (size_t j = 0; j < n; ++j)
      if ((spot_[j] - spot_[i]).norm() <= 1.5 * style_.spacing && excess_[j] > 0)
        centre += excess_[j] * spot_[j], weight += excess_[j];
    marks_.push_back(centre / weight);
    PlanPress(marks_.back(), normal_[i], 0.5 * style_.depth, -1, haptics::kButtonMark);
  }
}

}  // namespace vsurg::sim
