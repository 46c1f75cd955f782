// CutMembrane (cut_membrane.h): the patch's grid and springs, the walk of a cut along its edges
// with node snapping, and the separation of the triangles on either side of a cut edge.
#include "common/tissue/cut_membrane.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <tuple>
#include <utility>

#include "common/core/require.h"

namespace vsurg::tissue {

namespace {

constexpr double kPi = std::numbers::pi;

double Cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// The smallest angle of triangle (a, b, c), rad; a negative value when it is inverted (clockwise).
double MinAngle(const Vec2& a, const Vec2& b, const Vec2& c) {
  if (Cross(b - a, c - a) <= 0) return -1;
  const auto angle = [](const Vec2& at, const Vec2& p, const Vec2& q) {
    const Vec2 u = p - at, w = q - at;
    return std::atan2(std::abs(Cross(u, w)), u.dot(w));
  };
  return std::min({angle(a, b, c), angle(b, c, a), angle(c, a, b)});
}

}  // namespace

Status CheckCutMembrane(const CutMembraneParams& p) {
  for (const auto& [field, v, unit] :
       {std::tuple{"size_x", p.size_x, "m"}, std::tuple{"size_y", p.size_y, "m"},
        std::tuple{"thickness", p.thickness, "m"},
        std::tuple{"youngs_modulus", p.youngs_modulus, "Pa"},
        std::tuple{"density", p.density, "kg/m³"}}) {
    if (Status st = RequirePositive(field, v, unit); !st.ok()) return st;
  }
  if (p.cells < 2 || p.cells > 256) return InvalidArgument("cells", "cells: must be 2 to 256");
  if (!(std::isfinite(p.damping) && p.damping >= 0))
    return InvalidArgument("damping", "damping: must be ≥ 0 N·s/m");
  if (!(p.pretension >= 0 && p.pretension < 0.5))
    return InvalidArgument("pretension", "pretension: must be in [0, 0.5)");
  if (!(p.snap_fraction >= 0 && p.snap_fraction <= 0.5))
    return InvalidArgument("snap_fraction", "snap_fraction: must be in [0, 0.5]");
  if (!(p.min_angle_deg >= 0 && p.min_angle_deg <= 40))
    return InvalidArgument("min_angle_deg", "min_angle_deg: must be in [0, 40]");
  if (!(p.advance_fraction > 0 && p.advance_fraction <= 1))
    return InvalidArgument("advance_fraction", "advance_fraction: must be in (0, 1]");
  if (!(p.failure_strain > 0 && p.failure_strain <= 10))
    return InvalidArgument("failure_strain", "failure_strain: must be in (0, 10]");
  if (p.max_particles < 0 || p.max_particles > 1 << 22)
    return InvalidArgument("max_particles", "max_particles: must be 0 to 4194304");
  return Status::Ok();
}

Expected<CutMembrane> CutMembrane::Create(const CutMembraneParams& params) {
  if (Status st = CheckCutMembrane(params); !st.ok()) return st.error();
  CutMembrane m;
  m.p_ = params;
  m.BuildGrid();
  if (Status st = m.BuildModel(); !st.ok()) return st.error();
  return m;
}

// Nodes row by row on a triangular lattice: edge h = size_x / cells across, rows about h √3 / 2
// apart, every other row shifted by h / 2 and closed at the frame by a node at each end; two rows
// joined by a zipper that always advances the row whose next node is nearer, so the triangles are
// equilateral inside and 30-60-90 at the sides. Every interior node has six neighbours 60° apart:
// whatever the blade's direction, a neighbour lies within 30° of it, half an edge or less off its
// line, where snapping may reach.
void CutMembrane::BuildGrid() {
  h_ = p_.size_x / p_.cells;
  const int rows =
      std::max(2, static_cast<int>(std::lround(p_.size_y / (h_ * std::sqrt(3.0) / 2))));
  // The rows exactly h √3 / 2 apart (size_y rounded to whole rows): a lattice of equilateral
  // triangles under the frame's uniform pre-strain is in equilibrium as it is.
  const double dy = h_ * std::sqrt(3.0) / 2, x0 = -0.5 * p_.size_x, x1 = 0.5 * p_.size_x;
  p_.size_y = rows * dy;
  std::vector<std::vector<int>> lattice(rows + 1);
  for (int j = 0; j <= rows; ++j) {
    const double y = -0.5 * p_.size_y + j * dy;
    std::vector<double> xs;
    if (j % 2 == 0) {
      for (int i = 0; i <= p_.cells; ++i) xs.push_back(x0 + i * h_);
    } else {
      xs.push_back(x0);
      for (int i = 0; i < p_.cells; ++i) xs.push_back(x0 + (i + 0.5) * h_);
      xs.push_back(x1);
    }
    for (size_t i = 0; i < xs.size(); ++i) {
      lattice[j].push_back(static_cast<int>(node_rest_.size()));
      node_rest_.emplace_back(xs[i], y);
      node_fixed_.push_back(j == 0 || j == rows || i == 0 || i + 1 == xs.size());
    }
  }
  const auto add = [this](int a, int b, int c) {
    Tri t;
    if (Cross(node_rest_[b] - node_rest_[a], node_rest_[c] - node_rest_[a]) < 0) std::swap(b, c);
    t.v = t.n = {a, b, c};
    t.spring = t.across = {-1, -1, -1};
    tris_.push_back(t);
  };
  for (int j = 0; j < rows; ++j) {
    const std::vector<int>&lo = lattice[j], &hi = lattice[j + 1];
    size_t a = 0, b = 0;
    while (a + 1 < lo.size() || b + 1 < hi.size()) {
      const auto shape = [this](int p, int q, int r) {
        return std::abs(MinAngle(node_rest_[p], node_rest_[q], node_rest_[r])) +
               std::abs(MinAngle(node_rest_[p], node_rest_[r], node_rest_[q])) - 1;
      };
      bool lo_next = b + 1 >= hi.size();
      if (!lo_next && a + 1 < lo.size()) {  // the nearer next node; at a tie, the better shape
        const double lx = node_rest_[lo[a + 1]].x(), hx = node_rest_[hi[b + 1]].x();
        lo_next = std::abs(lx - hx) > 1e-6 * h_
                      ? lx < hx
                      : shape(lo[a], lo[a + 1], hi[b]) >= shape(lo[a], hi[b + 1], hi[b]);
      }
      if (lo_next) {
        add(lo[a], lo[a + 1], hi[b]), ++a;
      } else {
        add(lo[a], hi[b + 1], hi[b]), ++b;
      }
    }
  }
  const int nodes = static_cast<int>(node_rest_.size());
  node_on_cut_.assign(nodes, false);
  fan_.assign(nodes, {-1, -1, -1, -1, -1, -1, -1, -1});
  adj_.assign(nodes, {-1, -1, -1, -1, -1, -1, -1, -1});
  adj_cut_.assign(nodes, {});
  std::map<std::pair<int, int>, std::pair<int, int>> edges;  // (a, b) → (triangle, its edge)
  for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = tris_[t].n[k], b = tris_[t].n[(k + 1) % 3];
      *std::find(fan_[a].begin(), fan_[a].end(), -1) = t;  // at most eight around a node
      for (auto [u, w] : {std::pair{a, b}, std::pair{b, a}}) {
        auto& row = adj_[u];
        if (std::find(row.begin(), row.end(), w) == row.end())
          *std::find(row.begin(), row.end(), -1) = w;
      }
      if (auto it = edges.find({b, a}); it != edges.end()) {
        tris_[t].across[k] = it->second.first;
        tris_[it->second.first].across[it->second.second] = t;
      } else {
        edges[{a, b}] = {t, k};
      }
    }
  }
  label_.assign(tris_.size(), 0);
  stack_.reserve(tris_.size());
}

double CutMembrane::RestLength(const Tri& t, int k) const {
  return (node_rest_[t.n[k]] - node_rest_[t.n[(k + 1) % 3]]).norm() * (1.0 - p_.pretension);
}

// The springs (three per triangle, Van Gelder's stiffness), the lumped masses, the rim held, the
// room for the cuts' copies; then each triangle is told which of the (sorted) springs are its own.
Status CutMembrane::BuildModel() {
  MassSpringSystem sys;
  for (const Vec2& r : node_rest_) sys.rest_positions.emplace_back(r.x(), r.y(), 0.0);
  sys.masses.assign(node_rest_.size(), 0.0);
  for (const Tri& t : tris_) {
    const double area = 0.5 * Cross(node_rest_[t.n[1]] - node_rest_[t.n[0]],
                                    node_rest_[t.n[2]] - node_rest_[t.n[0]]);
    for (int k = 0; k < 3; ++k) {
      sys.masses[t.n[k]] += p_.density * p_.thickness * area / 3.0;
      const double len = (node_rest_[t.n[k]] - node_rest_[t.n[(k + 1) % 3]]).norm();
      const double stiffness = p_.youngs_modulus * p_.thickness * area / (len * len);
      sys.springs.push_back({t.n[k], t.n[(k + 1) % 3], stiffness, p_.damping, RestLength(t, k)});
    }
  }
  sys.surface_particles = static_cast<int>(node_rest_.size());
  MassSpringStepParams step;
  step.integrator = Integrator::kImplicitEuler;
  step.cg_max_iterations = 100;
  step.divergence_distance = std::max(p_.size_x, p_.size_y);
  auto model = MassSpringModel::Create(std::move(sys), step);
  if (!model.ok()) return model.error();
  model_ = std::move(*model);
  const int nodes = static_cast<int>(node_rest_.size());
  model_->ReserveParticles(ParticleRoom());
  node_of_.reserve(ParticleRoom());
  for (int i = 0; i < nodes; ++i) {
    node_of_.push_back(i);
    if (node_fixed_[i]) model_->SetFixed(i, true);
  }
  std::multimap<std::pair<int, int>, int> springs;  // sorted springs by their ends
  const auto& all = model_->system().springs;
  for (int s = 0; s < static_cast<int>(all.size()); ++s)
    springs.insert({{std::min(all[s].i, all[s].j), std::max(all[s].i, all[s].j)}, s});
  for (Tri& t : tris_) {
    for (int k = 0; k < 3; ++k) {
      const int a = t.n[k], b = t.n[(k + 1) % 3];
      auto it = springs.find({std::min(a, b), std::max(a, b)});
      if (it == springs.end())
        return Error{ErrorCode::kNumerical, "a triangle lost its spring", ""};
      t.spring[k] = it->second;
      springs.erase(it);
    }
  }
  return Status::Ok();
}

int CutMembrane::ParticleRoom() const {
  const int nodes = static_cast<int>(node_rest_.size());
  return std::max(p_.max_particles > 0 ? p_.max_particles : 2 * nodes, nodes);
}

Vec2 CutMembrane::Rest(int particle) const {
  return node_rest_[node_of_[particle]];
}

bool CutMembrane::EdgeCut(int a, int b) const {
  for (int k = 0; k < kMaxFan; ++k)
    if (adj_[a][k] == b) return adj_cut_[a][k] != 0;
  return false;
}

int CutMembrane::NearestNode(const Vec2& p, bool on_cut_only, double within) const {
  int best = -1;
  double best_d = within * within;
  for (int i = 0; i < node_count(); ++i) {
    if (on_cut_only && !node_on_cut_[i]) continue;
    const double d = (node_rest_[i] - p).squaredNorm();
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

// The next node of a cut from `a` toward `to` along the blade's line (through `on` in direction
// `dir`): of the neighbours within 46° of the direction to `to` (every direction has one in a grid
// whose nodes have four or eight neighbours) that `to` has passed advance_fraction of the edge
// to, the one nearest the line (the least snap). -1 when none, or when the neighbour the direction
// points at most closely is across a cut edge (the blade runs back along its own cut, which opens
// nothing new).
int CutMembrane::NextNode(int a, const Vec2& to, const Vec2& on, const Vec2& dir) const {
  const Vec2 d = to - node_rest_[a];
  const double len = d.norm();
  if (!(len > 1e-9)) return -1;
  int best = -1;
  double best_cos = 0.69, best_off = INFINITY;
  bool closest_cut = false;
  for (int k = 0; k < kMaxFan && adj_[a][k] >= 0; ++k) {
    const Vec2 e = node_rest_[adj_[a][k]] - node_rest_[a];
    const double el = e.norm(), along = e.dot(d) / el, c = along / len;
    if (c <= 0.69) continue;
    if (c > best_cos) best_cos = c, closest_cut = adj_cut_[a][k] != 0;
    if (adj_cut_[a][k] || along < p_.advance_fraction * el) continue;
    const Vec2 r = node_rest_[adj_[a][k]] - on;
    if (const double off = std::abs(r.x() * dir.y() - r.y() * dir.x()); off < best_off)
      best_off = off, best = adj_[a][k];
  }
  return closest_cut ? -1 : best;
}

bool CutMembrane::SnapKeepsQuality(int node, const Vec2& at) const {
  const double bound = p_.min_angle_deg * kPi / 180;
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {
    const Tri& t = tris_[fan_[node][k]];
    std::array<Vec2, 3> c;
    for (int q = 0; q < 3; ++q) c[q] = t.n[q] == node ? at : node_rest_[t.n[q]];
    if (MinAngle(c[0], c[1], c[2]) < bound) return false;
  }
  return true;
}

// Moves `node` onto the line from `a` toward `to` when that is a small move that keeps the
// triangles around it well shaped.
void CutMembrane::Snap(int node, const Vec2& a, const Vec2& to) {
  const Vec2 d = (to - a).normalized();
  SnapTo(node, a + (node_rest_[node] - a).dot(d) * d);
}

// A node on the rim or on a cut stays where it is; else it moves to `at` when that is within
// snap_fraction of an edge and leaves its triangles' angles at min_angle or more.
void CutMembrane::SnapTo(int node, const Vec2& at) {
  if (node_fixed_[node] || node_on_cut_[node] || !at.allFinite()) return;
  if ((at - node_rest_[node]).norm() > p_.snap_fraction * h_ || !SnapKeepsQuality(node, at)) return;
  node_rest_[node] = at;
  model_->SetRestPosition(node, Vec3(at.x(), at.y(), 0.0));  // not yet split: its one particle
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {
    const Tri& t = tris_[fan_[node][k]];
    for (int e = 0; e < 3; ++e) {
      const auto& sp = model_->system().springs[t.spring[e]];
      model_->SetSpring(t.spring[e], sp.i, sp.j, RestLength(t, e));
    }
  }
  ShareMasses(node);
  for (int k = 0; k < kMaxFan && adj_[node][k] >= 0; ++k) ShareMasses(adj_[node][k]);
  ++snaps_;
}

int CutMembrane::Cut(const Vec2& from, const Vec2& to) {
  if (!from.allFinite() || !to.allFinite()) return 0;
  const Vec2 half(0.5 * p_.size_x, 0.5 * p_.size_y);
  if ((from.cwiseAbs() - half).maxCoeff() > h_ || (to.cwiseAbs() - half).maxCoeff() > h_) return 0;
  // The cut continues from its front while the blade is near it; else from the nearest node on a
  // cut (a branch, or a cut taken up again elsewhere).
  int a = front_ >= 0 && (node_rest_[front_] - from).norm() <= h_ ? front_ : -1;
  if (a < 0) a = NearestNode(from, true, h_);
  if (a < 0) {  // a new cut: it starts at the node nearest the blade, moved under it if it may
    a = NearestNode(from, false, 2 * h_);
    if (a < 0) return 0;
    SnapTo(a, from);
    node_on_cut_[a] = true;
  }
  int cut = 0;
  for (int guard = 0; guard < 8 * p_.cells; ++guard) {
    // The blade's own line (from, to) where it has one, else the line from a to `to`.
    const bool own = (to - from).norm() > 1e-3 * h_;
    const Vec2 on = own ? from : node_rest_[a], dir = (to - on).normalized();
    const int b = NextNode(a, to, on, dir);
    if (b < 0) break;
    Snap(b, on, to);
    CutEdge(a, b);
    ++cut;
    a = b;
  }
  front_ = a;
  return cut;
}

void CutMembrane::CutEdge(int a, int b) {
  const bool closes = node_on_cut_[b];
  for (auto [u, w] : {std::pair{a, b}, std::pair{b, a}})
    for (int k = 0; k < kMaxFan; ++k)
      if (adj_[u][k] == w) adj_cut_[u][k] = 1;
  node_on_cut_[a] = node_on_cut_[b] = true;
  cut_.push_back({a, b});
  SeparateFan(a);
  SeparateFan(b);
  if (closes) FreeLoosePieces();
}

// The triangles around `node` fall into wedges that uncut edges join. Each wedge keeps the
// particle its triangles have, but for the second and later wedges on one particle: each of those
// is given a copy of it, with its triangles' corners and springs moved to the copy.
void CutMembrane::SeparateFan(int node) {
  std::array<int, kMaxFan> fan{}, root{}, corner{};
  int n = 0;
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {
    const Tri& t = tris_[fan_[node][k]];
    if (t.removed) continue;
    fan[n] = fan_[node][k], root[n] = n;
    corner[n++] = static_cast<int>(std::find(t.n.begin(), t.n.end(), node) - t.n.begin());
  }
  const auto find = [&root](int i) {
    while (root[i] != i) i = root[i];
    return i;
  };
  for (int i = 0; i < n; ++i) {
    const Tri& t = tris_[fan[i]];
    for (int e = 0; e < 3; ++e) {
      const int other = t.across[e], u = t.n[e], w = t.n[(e + 1) % 3];
      if (other < 0 || (u != node && w != node) || EdgeCut(u, w)) continue;
      for (int j = 0; j < n; ++j)
        if (fan[j] == other) root[find(i)] = find(j);
    }
  }
  std::array<int, kMaxFan> wedge_root{}, wedge_particle{};
  int wedges = 0;
  for (int i = 0; i < n; ++i) {
    const int r = find(i), particle = tris_[fan[i]].v[corner[i]];
    int q = 0;
    while (q < wedges && wedge_root[q] != r) ++q;
    if (q == wedges) {  // a wedge seen first: its particle, or a copy if an earlier wedge has it
      bool taken = false;
      for (int o = 0; o < wedges; ++o) taken = taken || wedge_particle[o] == particle;
      int own = particle;
      if (taken) {
        own = model_->SplitParticle(particle, model_->system().masses[particle]);
        if (own < 0) return;  // the room reserved is full: this node stays joined
        node_of_.push_back(node);
      }
      wedge_root[wedges] = r, wedge_particle[wedges++] = own;
    }
    if (wedge_particle[q] != particle) MoveCorner(fan[i], corner[i], wedge_particle[q]);
  }
  ShareMasses(node);
}

// Triangle t's corner given to `particle`, with the two springs at that corner.
void CutMembrane::MoveCorner(int t, int corner, int particle) {
  Tri& tri = tris_[t];
  const int old = tri.v[corner];
  tri.v[corner] = particle;
  for (int e = 0; e < 3; ++e) {
    const auto& sp = model_->system().springs[tri.spring[e]];
    if (sp.i != old && sp.j != old) continue;
    model_->SetSpring(tri.spring[e], sp.i == old ? particle : sp.i, sp.j == old ? particle : sp.j,
                      RestLength(tri, e));
  }
}

// Each particle of `node` weighs a third of its triangles' (rest) mass.
void CutMembrane::ShareMasses(int node) {
  std::array<int, kMaxFan> particles{};
  std::array<double, kMaxFan> mass{};
  int n = 0;
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {
    const Tri& t = tris_[fan_[node][k]];
    if (t.removed) continue;
    const double area = 0.5 * std::abs(Cross(node_rest_[t.n[1]] - node_rest_[t.n[0]],
                                             node_rest_[t.n[2]] - node_rest_[t.n[0]]));
    const int p = t.v[std::find(t.n.begin(), t.n.end(), node) - t.n.begin()];
    int q = 0;
    while (q < n && particles[q] != p) ++q;
    if (q == n) particles[n] = p, mass[n++] = 0;
    mass[q] += p_.density * p_.thickness * area / 3.0;
  }
  for (int q = 0; q < n; ++q) model_->SetMass(particles[q], mass[q]);
}

// After a cut closed on itself: the triangles flooded across uncut edges; a piece that holds no
// node of the rim is free, and is taken out.
void CutMembrane::FreeLoosePieces() {
  std::fill(label_.begin(), label_.end(), 0);
  int next = 0;
  for (int seed = 0; seed < FaceCount(); ++seed) {
    if (tris_[seed].removed || label_[seed] != 0) continue;
    bool held = false;
    label_[seed] = ++next;
    stack_.clear();
    stack_.push_back(seed);
    while (!stack_.empty()) {
      const Tri& t = tris_[stack_.back()];
      stack_.pop_back();
      for (int e = 0; e < 3; ++e) {
        held = held || node_fixed_[t.n[e]];
        const int o = t.across[e];
        if (o < 0 || label_[o] != 0 || tris_[o].removed || EdgeCut(t.n[e], t.n[(e + 1) % 3]))
          continue;
        label_[o] = next;
        stack_.push_back(o);
      }
    }
    if (!held) FreePiece(next);
  }
}

void CutMembrane::FreePiece(int label) {
  for (int t = 0; t < FaceCount(); ++t) {
    if (label_[t] != label) continue;
    tris_[t].removed = true;
    for (int p : tris_[t].v) {
      model_->SetFixed(p, true);
      if (std::find(loaded_.begin(), loaded_.begin() + loaded_count_, p) !=
          loaded_.begin() + loaded_count_)
        ClearLoad();
      if (p == held_) Release();
    }
  }
  ++freed_;
}

bool CutMembrane::Step(double dt) {
  return model_->Step(dt);
}

// The particle of the node nearest `at` on the side of any cut that `at` lies on (the wedge of
// triangles that holds it); -1 on the rim or off the patch.
int CutMembrane::ParticleUnder(const Vec2& at) const {
  const int node = NearestNode(at, false, 2 * h_);
  if (node < 0 || node_fixed_[node]) return -1;
  int particle = -1;
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {
    const Tri& t = tris_[fan_[node][k]];
    if (t.removed) continue;
    const Vec2 a = node_rest_[t.n[0]], b = node_rest_[t.n[1]], c = node_rest_[t.n[2]];
    const int corner = static_cast<int>(std::find(t.n.begin(), t.n.end(), node) - t.n.begin());
    if (particle < 0) particle = t.v[corner];
    if (Cross(b - a, at - a) >= 0 && Cross(c - b, at - b) >= 0 && Cross(a - c, at - c) >= 0)
      return t.v[corner];
  }
  return particle;
}

void CutMembrane::ClearLoad() {
  for (int i = 0; i < loaded_count_; ++i) model_->SetExternalForce(loaded_[i], Vec3::Zero());
  loaded_count_ = 0;
}

void CutMembrane::Load(const Vec2& at, const Vec3& force) {
  ClearLoad();
  if (!at.allFinite() || !force.allFinite() || force.isZero()) return;
  const int particle = ParticleUnder(at);
  if (particle < 0) return;
  const auto taken = [&](int q) {
    return std::find(loaded_.begin(), loaded_.begin() + loaded_count_, q) !=
           loaded_.begin() + loaded_count_;
  };
  loaded_[loaded_count_++] = particle;
  const int node = node_of_[particle];
  for (int k = 0; k < kMaxFan && fan_[node][k] >= 0; ++k) {  // the wedge's triangles
    const Tri& t = tris_[fan_[node][k]];
    if (t.removed || std::find(t.v.begin(), t.v.end(), particle) == t.v.end()) continue;
    for (int c = 0; c < 3; ++c)
      if (!node_fixed_[t.n[c]] && !taken(t.v[c]) && loaded_count_ < kMaxFan + 1)
        loaded_[loaded_count_++] = t.v[c];
  }
  const int around = loaded_count_ - 1;
  model_->SetExternalForce(particle, around > 0 ? Vec3(0.5 * force) : force);
  for (int i = 1; i < loaded_count_; ++i)
    model_->SetExternalForce(loaded_[i], Vec3(0.5 * force / around));
}

void CutMembrane::Hold(const Vec2& at, const Vec3& target, double stiffness) {
  const int kept = held_ >= 0 && at == hold_at_ ? held_ : -1;  // the same jaws, moved
  Release();
  if (!at.allFinite() || !target.allFinite() || !(stiffness > 0 && std::isfinite(stiffness)))
    return;
  const int particle = kept >= 0 ? kept : ParticleUnder(at);
  if (particle < 0) return;
  hold_at_ = at;
  const double damping = 2 * std::sqrt(stiffness * model_->system().masses[particle]);
  model_->SetAnchor(particle, target, stiffness, damping);
  held_ = particle, hold_target_ = target, hold_k_ = stiffness;
}

void CutMembrane::Release() {
  if (held_ >= 0) model_->ClearAnchors();
  held_ = -1;
}

Vec3 CutMembrane::HoldForce() const {
  return held_ < 0 ? Vec3::Zero() : Vec3(hold_k_ * (model_->positions()[held_] - hold_target_));
}

// An interior edge has a spring on each side; it tears when both have failed (a rim edge, its
// one). Strain over the spring's unloaded length.
int CutMembrane::Tear(const Vec2& blade, double spare) {
  const auto& springs = model_->system().springs;
  const auto& x = model_->positions();
  const auto failed = [&](int s) {
    const Spring& sp = springs[s];
    return sp.rest_length > 0 &&
           (x[sp.i] - x[sp.j]).norm() > (1 + p_.failure_strain) * sp.rest_length;
  };
  int tore = 0;
  for (int t = 0; t < FaceCount(); ++t) {
    const Tri& tri = tris_[t];
    if (tri.removed) continue;
    for (int e = 0; e < 3; ++e) {
      const int a = tri.n[e], b = tri.n[(e + 1) % 3], o = tri.across[e];
      if (o >= 0 && o < t) continue;  // each edge once, from its lower triangle
      if (EdgeCut(a, b) || !failed(tri.spring[e])) continue;
      if ((node_rest_[a] - blade).norm() < spare || (node_rest_[b] - blade).norm() < spare)
        continue;
      if (o >= 0) {
        const Tri& other = tris_[o];
        int k = 0;
        while (k < 3 && !(other.n[k] == b && other.n[(k + 1) % 3] == a)) ++k;
        if (k < 3 && !other.removed && !failed(other.spring[k])) continue;
      }
      CutEdge(a, b);
      ++tore;
    }
  }
  torn_ += tore;
  return tore;
}

// A point force in the plane of a sheet (plane stress, Kelvin's solution) displaces its point of
// application, relative to a rim at R, by u = F (1 + ν)(3 − ν) ln(R / r₀) / (4π E t), with r₀ half
// an edge (the load's spread) and ν = 1/3, the Poisson ratio of a lattice of equal central springs
// on equilateral triangles.
double CutMembrane::InPlaneStiffness() const {
  constexpr double nu = 1.0 / 3;
  const double radius = 0.5 * std::min(p_.size_x, p_.size_y);
  return 4 * kPi * p_.youngs_modulus * p_.thickness /
         ((1 + nu) * (3 - nu) * std::log(radius / (0.5 * h_)));
}

// A point load on a taut membrane of tension T (N/m) and radius R: w = F ln(R / r₀) / (2π T),
// with T = E t ε the frame's pre-strain and r₀ half a cell (the load's spread).
double CutMembrane::NormalStiffness() const {
  const double tension = p_.youngs_modulus * p_.thickness * p_.pretension;
  const double radius = 0.5 * std::min(p_.size_x, p_.size_y);
  return 2 * kPi * tension / std::log(radius / (0.5 * h_));
}

}  // namespace vsurg::tissue
