#include "common/tissue/coil_deformation.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include <Eigen/Geometry>

#include "common/tissue/simd.h"

namespace vsurg::tissue {

using geometry::Vec3;

namespace {
// Vertices whose ρ differ by less than this share one angle (1 nm: far below any mesh spacing;
// the angle error it allows is slope × 1 nm).
constexpr double kGroupTolerance = 1e-9;

// Group g turns by θ_g = Θ_{k−1} + t_g (Θ_k − Θ_{k−1}); each of its runs of rows turns a stretch
// of consecutive vertices: out[k] = rest[k] + d[k] (cos θ − 1) + q[k] sin θ over the run's
// 3·count coordinates, one flat loop the compiler vectorises (the rows keep x, y, z interleaved
// as the mesh's positions do). Built twice, for x86-64-v3 (AVX2 and FMA: four coordinates an
// instruction) and the baseline, the loader picking the one the CPU runs.
struct Rows {
  const int32_t *group_ring, *group_run, *run_row, *run_vertex;
  const double *group_t, *rest, *d, *q;
};
VSURG_SIMD_CLONES
void TurnGroups(int groups, const double* angles, const Rows& rows, double* __restrict out) {
  for (int g = 0; g < groups; ++g) {
    const int ring = rows.group_ring[g];
    const double theta = angles[ring - 1] + rows.group_t[g] * (angles[ring] - angles[ring - 1]);
    const double cm1 = std::cos(theta) - 1.0, sn = std::sin(theta);
    for (int r = rows.group_run[g]; r < rows.group_run[g + 1]; ++r) {
      const int begin = 3 * rows.run_row[r], count = 3 * (rows.run_row[r + 1] - rows.run_row[r]);
      const double* __restrict x = rows.rest + begin;
      const double* __restrict d = rows.d + begin;
      const double* __restrict q = rows.q + begin;
      double* __restrict o = out + 3 * static_cast<ptrdiff_t>(rows.run_vertex[r]);
      if (count == 3) {  // a lone vertex (a surface's geodesic groups): no vector loop set-up
        for (int k = 0; k < 3; ++k) o[k] = x[k] + d[k] * cm1 + q[k] * sn;
        continue;
      }
      for (int k = 0; k < count; ++k) o[k] = x[k] + d[k] * cm1 + q[k] * sn;
    }
  }
}

// The rows' order (vertices by ascending ρ), cut into groups of equal ρ and, within a group, runs
// of consecutive mesh indices (a limb's group is a ring or two, so its runs are long).
std::vector<int32_t> BindGroups(const std::vector<double>& rho, CoilTurnTable& t) {
  const int n = static_cast<int>(rho.size());
  std::vector<int32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return rho[a] < rho[b]; });
  for (int row = 0; row < n; ++row) {
    if (t.group_rho.empty() || !(rho[order[row]] - t.group_rho.back() <= kGroupTolerance)) {
      t.group_rho.push_back(rho[order[row]]);
      t.group_begin.push_back(row);
    }
  }
  t.group_begin.push_back(n);
  for (size_t g = 0; g + 1 < t.group_begin.size(); ++g) {
    std::sort(order.begin() + t.group_begin[g], order.begin() + t.group_begin[g + 1]);
    t.group_run.push_back(static_cast<int32_t>(t.run_row.size()));
    for (int row = t.group_begin[g]; row < t.group_begin[g + 1]; ++row) {
      if (row == t.group_begin[g] || order[row] != order[row - 1] + 1) {
        t.run_row.push_back(row);
        t.run_vertex.push_back(order[row]);
      }
    }
  }
  t.group_run.push_back(static_cast<int32_t>(t.run_row.size()));
  t.run_row.push_back(n);
  return order;
}

// Each group's coil and place in it, as TwistAt finds them (the state changes only the boundary
// angles; a group inside the cutoff R_P is in a coil k <= P), and the groups inside each R_P.
void BindCoils(const CoilSpringModel& model, CoilTurnTable& t) {
  const CoilSpringParams& cp = model.params();
  const int coils = model.coils();
  t.group_ring.resize(t.group_rho.size());
  t.group_t.resize(t.group_rho.size());
  for (size_t g = 0; g < t.group_rho.size(); ++g) {
    const double r = std::abs(t.group_rho[g]);
    if (r <= cp.core_radius) {
      t.group_ring[g] = 1, t.group_t[g] = 0;  // the core turns with Θ_0
      continue;
    }
    const int k =
        std::clamp(static_cast<int>(std::ceil((r - cp.core_radius) / cp.thickness)), 1, coils);
    t.group_ring[g] = k;
    t.group_t[g] = std::clamp((r - model.RingRadius(k - 1)) / cp.thickness, 0.0, 1.0);
  }
  t.groups_within.assign(coils + 1, 0);
  for (int p = 1; p <= coils; ++p)
    t.groups_within[p] = static_cast<int32_t>(
        std::lower_bound(t.group_rho.begin(), t.group_rho.end(), model.RingRadius(p)) -
        t.group_rho.begin());
}

Rows RowsOf(const CoilTurnTable& t) {
  return {t.group_ring.data(), t.group_run.data(), t.run_row.data(), t.run_vertex.data(),
          t.group_t.data(),    t.rest_rows.data(), t.d_rows.data(),  t.q_rows.data()};
}

// The groups a state turns: those strictly inside R_P (θ(R_P) = 0); a zero twist moves nothing.
int TurnedGroups(const CoilTurnTable& t, const CoilState& state) {
  if (state.cutoff <= 0 || state.total_twist == 0) return 0;
  return t.groups_within[std::min<size_t>(state.cutoff, t.groups_within.size() - 1)];
}

DeformStats StatsOf(const CoilState& state, int moved_vertices) {
  DeformStats stats;
  stats.cutoff = state.cutoff;
  stats.overload = state.overload;
  stats.torque = state.torque;
  stats.total_twist = state.total_twist;
  stats.moved_vertices = moved_vertices;  // touched_vertices 0: Apply's to say
  return stats;
}
}  // namespace

void CoilDeformer::Bind(const std::vector<Vec3>& rest, const std::vector<double>& rho,
                        const std::vector<Vec3>& foot, const std::vector<Vec3>& axis) {
  const int n = static_cast<int>(rest.size());
  CoilTurnTable t;
  t.rest = rest;
  t.rho_by_vertex = rho;
  deformed_ = rest;
  state_ = model_.MakeState();
  const std::vector<int32_t> order = BindGroups(rho, t);
  for (auto* v : {&t.rest_rows, &t.d_rows, &t.q_rows}) v->resize(3 * static_cast<size_t>(n));
  for (int row = 0; row < n; ++row) {
    const int v = order[row];
    Vec3 d = rest[v] - foot[v];
    d -= d.dot(axis[v]) * axis[v];  // keep only the part ⊥ axis: the rotation preserves |d|
    const Vec3 q = axis[v].cross(d);
    for (int c = 0; c < 3; ++c) {
      t.rest_rows[3 * row + c] = rest[v][c];
      t.d_rows[3 * row + c] = d[c];
      t.q_rows[3 * row + c] = q[c];
    }
  }
  BindCoils(model_, t);
  table_ = std::make_shared<const CoilTurnTable>(std::move(t));
  moved_groups_ = 0;
}

Expected<CoilDeformer> CoilDeformer::CreateForLimb(const CoilSpringModel& model,
                                                   const std::vector<Vec3>& rest,
                                                   const std::vector<Vec3>& centreline,
                                                   double grasp_arc_length) {
  if (rest.empty()) return InvalidArgument("mesh", "mesh has no vertices");
  auto proj = geometry::ProjectOntoPolyline(rest, centreline);
  if (!proj.ok()) return proj.error();
  return CreateForLimb(model, rest, *proj, geometry::ArcLengths(centreline).back(),
                       grasp_arc_length);
}

Expected<CoilDeformer> CoilDeformer::CreateForLimb(
    const CoilSpringModel& model, const std::vector<Vec3>& rest,
    const std::vector<geometry::CentrelineProjection>& projection, double centreline_length,
    double grasp_arc_length) {
  if (rest.empty()) return InvalidArgument("mesh", "mesh has no vertices");
  if (projection.size() != rest.size())
    return InvalidArgument("centreline", "one projection per vertex is needed (" +
                                             std::to_string(projection.size()) + " for " +
                                             std::to_string(rest.size()) + ")");
  const double length = centreline_length;
  if (!std::isfinite(grasp_arc_length) || grasp_arc_length < 0 || grasp_arc_length > length) {
    return InvalidArgument("grasp", "grasp position along the centreline must be in [0, " +
                                        std::to_string(length) + "] m");
  }
  const int n = static_cast<int>(rest.size());
  std::vector<double> rho(n);
  std::vector<Vec3> foot(n), axis(n);
  for (int v = 0; v < n; ++v) {
    if (!rest[v].allFinite())
      return InvalidArgument("mesh", "vertex " + std::to_string(v) + " is not finite");
    rho[v] = std::abs(projection[v].s - grasp_arc_length);
    foot[v] = projection[v].point;
    axis[v] = projection[v].tangent;
  }
  CoilDeformer d(model, TwistMode::kLimb);
  d.Bind(rest, rho, foot, axis);
  return d;
}

Expected<CoilDeformer> CoilDeformer::CreateForSurface(const CoilSpringModel& model,
                                                      const geometry::TriMesh& rest,
                                                      const geometry::SurfacePoint& grasp,
                                                      geometry::GeodesicMethod method) {
  auto dist = geometry::GeodesicDistances(rest, grasp, method);
  if (!dist.ok()) return dist.error();
  const Vec3 g = geometry::PositionOf(rest, grasp);
  const Vec3 axis_dir = geometry::NormalOf(rest, grasp);
  if (!(axis_dir.norm() > 0.5)) {
    return InvalidArgument("grasp", "the grasp triangle is degenerate: no surface normal");
  }
  const int n = rest.VertexCount();
  std::vector<Vec3> foot(n), axis(n, axis_dir);
  for (int v = 0; v < n; ++v) foot[v] = g + (rest.positions[v] - g).dot(axis_dir) * axis_dir;
  CoilDeformer d(model, TwistMode::kSurface);
  d.Bind(rest.positions, *dist, foot, axis);
  return d;
}

DeformStats CoilDeformer::Update(double torque) {
  model_.Forward(torque, state_);
  return Apply(state_);
}

DeformStats CoilDeformer::Apply(const CoilState& state) {
  if (&state != &state_) state_ = state;  // same sizes: no allocation
  const CoilTurnTable& t = *table_;
  const int groups = TurnedGroups(t, state);
  double* out = deformed_.data()->data();
  TurnGroups(groups, state.boundary_angles.data(), RowsOf(t), out);
  // Put back at rest what the previous update moved and this one does not.
  for (int r = t.group_run[groups]; r < t.group_run[std::max(groups, moved_groups_)]; ++r) {
    std::copy(t.rest_rows.begin() + 3 * t.run_row[r], t.rest_rows.begin() + 3 * t.run_row[r + 1],
              out + 3 * static_cast<ptrdiff_t>(t.run_vertex[r]));
  }
  DeformStats stats = StatsOf(state, t.group_begin[groups]);
  stats.touched_vertices = t.group_begin[std::max(groups, moved_groups_)];
  moved_groups_ = groups;
  return stats;
}

DeformStats CoilDeformer::Evaluate(double torque) {
  model_.Forward(torque, state_);
  return StatsOf(state_, table_->group_begin[TurnedGroups(*table_, state_)]);
}

void CoilDeformer::TurnFromRest(const CoilTurnTable& table, const CoilState& state,
                                std::vector<Vec3>& out) {
  out.assign(table.rest.begin(), table.rest.end());
  TurnGroups(TurnedGroups(table, state), state.boundary_angles.data(), RowsOf(table),
             out.data()->data());
}

}  // namespace vsurg::tissue
