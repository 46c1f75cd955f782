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
}  // namespace

void CoilDeformer::Bind(const std::vector<Vec3>& rest, const std::vector<double>& rho,
                        const std::vector<Vec3>& foot, const std::vector<Vec3>& axis) {
  const int n = static_cast<int>(rest.size());
  rest_ = rest;
  deformed_ = rest;
  rho_by_vertex_ = rho;
  state_ = model_.MakeState();
  std::vector<int32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return rho[a] < rho[b]; });
  group_rho_.clear();
  group_begin_.clear();
  for (int row = 0; row < n; ++row) {
    if (group_rho_.empty() || !(rho[order[row]] - group_rho_.back() <= kGroupTolerance)) {
      group_rho_.push_back(rho[order[row]]);
      group_begin_.push_back(row);
    }
  }
  group_begin_.push_back(n);
  // Within a group the vertices in mesh order, cut into runs of consecutive indices: a limb's
  // group is a ring or two, so its runs are long.
  run_row_.clear();
  run_vertex_.clear();
  group_run_.clear();
  for (size_t g = 0; g + 1 < group_begin_.size(); ++g) {
    std::sort(order.begin() + group_begin_[g], order.begin() + group_begin_[g + 1]);
    group_run_.push_back(static_cast<int32_t>(run_row_.size()));
    for (int row = group_begin_[g]; row < group_begin_[g + 1]; ++row) {
      if (row == group_begin_[g] || order[row] != order[row - 1] + 1) {
        run_row_.push_back(row);
        run_vertex_.push_back(order[row]);
      }
    }
  }
  group_run_.push_back(static_cast<int32_t>(run_row_.size()));
  run_row_.push_back(n);
  for (auto* v : {&rest_rows_, &d_rows_, &q_rows_}) v->resize(3 * static_cast<size_t>(n));
  for (int row = 0; row < n; ++row) {
    const int v = order[row];
    Vec3 d = rest[v] - foot[v];
    d -= d.dot(axis[v]) * axis[v];  // keep only the part ⊥ axis: the rotation preserves |d|
    const Vec3 q = axis[v].cross(d);
    for (int c = 0; c < 3; ++c) {
      rest_rows_[3 * row + c] = rest[v][c];
      d_rows_[3 * row + c] = d[c];
      q_rows_[3 * row + c] = q[c];
    }
  }
  // Each group's coil and place in it, as TwistAt finds them (the state changes only the
  // boundary angles; a group inside the cutoff R_P is in a coil k <= P).
  const CoilSpringParams& cp = model_.params();
  const int coils = model_.coils();
  group_ring_.resize(group_rho_.size());
  group_t_.resize(group_rho_.size());
  for (size_t g = 0; g < group_rho_.size(); ++g) {
    const double r = std::abs(group_rho_[g]);
    if (r <= cp.core_radius) {
      group_ring_[g] = 1, group_t_[g] = 0;  // the core turns with Θ_0
      continue;
    }
    const int k =
        std::clamp(static_cast<int>(std::ceil((r - cp.core_radius) / cp.thickness)), 1, coils);
    group_ring_[g] = k;
    group_t_[g] = std::clamp((r - model_.RingRadius(k - 1)) / cp.thickness, 0.0, 1.0);
  }
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
  const int p = state.cutoff;
  const double cutoff_radius = p > 0 ? model_.RingRadius(p) : 0.0;
  // Groups strictly inside R_P turn (θ(R_P) = 0); a zero twist moves nothing.
  int groups = 0;
  if (p > 0 && state.total_twist != 0) {
    groups = static_cast<int>(
        std::lower_bound(group_rho_.begin(), group_rho_.end(), cutoff_radius) - group_rho_.begin());
  }
  double* out = deformed_.data()->data();
  const Rows rows{group_ring_.data(), group_run_.data(), run_row_.data(), run_vertex_.data(),
                  group_t_.data(),    rest_rows_.data(), d_rows_.data(),  q_rows_.data()};
  TurnGroups(groups, state.boundary_angles.data(), rows, out);
  // Put back at rest what the previous update moved and this one does not.
  for (int r = group_run_[groups]; r < group_run_[std::max(groups, moved_groups_)]; ++r) {
    std::copy(rest_rows_.begin() + 3 * run_row_[r], rest_rows_.begin() + 3 * run_row_[r + 1],
              out + 3 * static_cast<ptrdiff_t>(run_vertex_[r]));
  }
  DeformStats stats;
  stats.cutoff = p;
  stats.overload = state.overload;
  stats.torque = state.torque;
  stats.total_twist = state.total_twist;
  stats.moved_vertices = group_begin_[groups];
  stats.touched_vertices = group_begin_[std::max(groups, moved_groups_)];
  moved_groups_ = groups;
  return stats;
}

}  // namespace vsurg::tissue
