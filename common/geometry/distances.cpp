#include "common/geometry/distances.h"

#include "common/geometry/bvh.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

namespace vsurg::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Multi-source Dijkstra over mesh edges; seeds carry their initial distance.
std::vector<double> DijkstraFrom(const TriMesh& mesh, const VertexAdjacency& adj,
                                 const std::vector<std::pair<int, double>>& seeds) {
  std::vector<double> dist(mesh.positions.size(), kInf);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  for (const auto& [v, d] : seeds) {
    if (d < dist[v]) {
      dist[v] = d;
      queue.emplace(d, v);
    }
  }
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > dist[v]) continue;
    for (int k = adj.offsets[v]; k < adj.offsets[v + 1]; ++k) {
      const int w = adj.neighbours[k];
      const double nd = d + (mesh.positions[w] - mesh.positions[v]).norm();
      if (nd < dist[w]) {
        dist[w] = nd;
        queue.emplace(nd, w);
      }
    }
  }
  return dist;
}

std::vector<std::pair<int, double>> Seeds(const TriMesh& mesh, const SurfacePoint& source) {
  const Vec3 p = PositionOf(mesh, source);
  std::vector<std::pair<int, double>> seeds;
  for (int v : mesh.triangles[source.triangle])
    seeds.emplace_back(v, (mesh.positions[v] - p).norm());
  return seeds;
}

// Heat method. With L the positive semi-definite cotangent Laplacian and A the lumped (barycentric)
// vertex areas: (1) solve (A + t·L) u = δ with t = h² (h the mean edge length); (2) per face
// X = −∇u/|∇u|; (3) solve L φ = −div X; (4) shift φ so the source is at distance 0.
Expected<std::vector<double>> HeatFrom(const TriMesh& mesh, const SurfacePoint& source,
                                       const std::vector<double>& reachable_dijkstra) {
  const int n = mesh.VertexCount();
  std::vector<Eigen::Triplet<double>> lap;
  lap.reserve(mesh.triangles.size() * 12);
  Eigen::VectorXd area = Eigen::VectorXd::Zero(n);
  double edge_sum = 0;
  int edge_count = 0;
  // Cotangents per face corner, kept for the divergence.
  std::vector<Vec3> cots(mesh.triangles.size(), Vec3::Zero());
  for (int f = 0; f < mesh.TriangleCount(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const double twice_area = 2.0 * TriangleArea(mesh, f);
    for (int k = 0; k < 3; ++k) {
      edge_sum += (mesh.positions[t[(k + 1) % 3]] - mesh.positions[t[k]]).norm();
      ++edge_count;
    }
    if (!(twice_area > 1e-300)) continue;  // a zero-area face carries no diffusion
    for (int k = 0; k < 3; ++k) {
      const int i = t[k], j = t[(k + 1) % 3], o = t[(k + 2) % 3];
      const Vec3 u = mesh.positions[i] - mesh.positions[o],
                 w = mesh.positions[j] - mesh.positions[o];
      const double cot = u.dot(w) / twice_area;  // cot of the angle at o, opposite edge ij
      cots[f][(k + 2) % 3] = cot;
      lap.emplace_back(i, j, -0.5 * cot);
      lap.emplace_back(j, i, -0.5 * cot);
      lap.emplace_back(i, i, 0.5 * cot);
      lap.emplace_back(j, j, 0.5 * cot);
      area[t[k]] += twice_area / 6.0;
    }
  }
  Eigen::SparseMatrix<double> L(n, n);
  L.setFromTriplets(lap.begin(), lap.end());
  const double h = edge_sum / std::max(1, edge_count);
  const double t = h * h;

  Eigen::SparseMatrix<double> heat = t * L;
  for (int i = 0; i < n; ++i) heat.coeffRef(i, i) += std::max(area[i], 1e-300);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> heat_solver(heat);
  if (heat_solver.info() != Eigen::Success) {
    return Error{ErrorCode::kNumerical, "heat method: heat operator factorisation failed", "mesh"};
  }
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < 3; ++k) delta[mesh.triangles[source.triangle][k]] = source.barycentric[k];
  const Eigen::VectorXd u = heat_solver.solve(delta);

  Eigen::VectorXd div = Eigen::VectorXd::Zero(n);
  for (int f = 0; f < mesh.TriangleCount(); ++f) {
    const Triangle& tri = mesh.triangles[f];
    const Vec3& p0 = mesh.positions[tri[0]];
    const Vec3& p1 = mesh.positions[tri[1]];
    const Vec3& p2 = mesh.positions[tri[2]];
    const Vec3 nrm = (p1 - p0).cross(p2 - p0);
    const double twice_area = nrm.norm();
    if (!(twice_area > 1e-300)) continue;
    const Vec3 nhat = nrm / twice_area;
    // ∇u = (1 / 2A) Σ u_i (N × e_i), e_i the edge opposite corner i, counter-clockwise.
    const Vec3 grad = (u[tri[0]] * nhat.cross(p2 - p1) + u[tri[1]] * nhat.cross(p0 - p2) +
                       u[tri[2]] * nhat.cross(p1 - p0)) /
                      twice_area;
    const double g = grad.norm();
    if (!(g > 0)) continue;
    const Vec3 x = -grad / g;
    // div at corner i: ½ Σ cot θ_1 (e_1·X) + cot θ_2 (e_2·X), e_1, e_2 leaving i.
    for (int k = 0; k < 3; ++k) {
      const int i = tri[k], j = tri[(k + 1) % 3], o = tri[(k + 2) % 3];
      const Vec3 e1 = mesh.positions[j] - mesh.positions[i];
      const Vec3 e2 = mesh.positions[o] - mesh.positions[i];
      // The angle opposite e1 (edge i→j) is at o; the angle opposite e2 (edge i→o) is at j.
      div[i] += 0.5 * (cots[f][(k + 2) % 3] * e1.dot(x) + cots[f][(k + 1) % 3] * e2.dot(x));
    }
  }
  // L is singular (constants); a tiny mass term makes it definite without moving the gradient.
  Eigen::SparseMatrix<double> poisson = L;
  for (int i = 0; i < n; ++i) poisson.coeffRef(i, i) += 1e-10 * std::max(area[i], 1e-300);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> poisson_solver(poisson);
  if (poisson_solver.info() != Eigen::Success) {
    return Error{ErrorCode::kNumerical, "heat method: Poisson factorisation failed", "mesh"};
  }
  const Eigen::VectorXd phi = poisson_solver.solve(-div);
  double at_source = 0;
  for (int k = 0; k < 3; ++k)
    at_source += source.barycentric[k] * phi[mesh.triangles[source.triangle][k]];
  std::vector<double> dist(n);
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(reachable_dijkstra[i])) {
      dist[i] = kInf;
    } else {
      dist[i] = std::max(0.0, phi[i] - at_source);
      if (!std::isfinite(dist[i])) {
        return Error{ErrorCode::kNumerical, "heat method produced a non-finite distance", "mesh"};
      }
    }
  }
  return dist;
}

}  // namespace

std::vector<double> ArcLengths(const std::vector<Vec3>& polyline) {
  std::vector<double> s(polyline.size(), 0.0);
  for (size_t i = 1; i < polyline.size(); ++i)
    s[i] = s[i - 1] + (polyline[i] - polyline[i - 1]).norm();
  return s;
}

namespace {
// One segment of a polyline with non-zero length: its start, unit direction, length and the arc
// length at its start (m).
struct PolylineSegment {
  Vec3 a = Vec3::Zero();
  Vec3 dir = Vec3::UnitZ();
  double len = 0, arc = 0;
};

// Calls f(segment) for each segment of non-zero length, in order.
template <typename F>
void ForEachSegment(const std::vector<Vec3>& polyline, F f) {
  double arc = 0;
  for (size_t i = 0; i + 1 < polyline.size(); ++i) {
    const Vec3 seg = polyline[i + 1] - polyline[i];
    const double len = seg.norm();
    if (!(len > 0)) continue;
    f(PolylineSegment{polyline[i], seg / len, len, arc});
    arc += len;
  }
}

// The nearest point to p over the segments offered, the first of equals kept.
class NearestOnPolyline {
 public:
  explicit NearestOnPolyline(const Vec3& p) : p_(p) {}
  void Offer(const PolylineSegment& s) {
    const Vec3 w = p_ - s.a;
    const double along = std::clamp(w.dot(s.dir), 0.0, s.len);
    const double d2 = (w - along * s.dir).squaredNorm();
    if (d2 < best_d2_) best_d2_ = d2, along_ = along, best_ = s;
  }
  CentrelineProjection Result() const {
    return {best_.arc + along_, best_.a + along_ * best_.dir, best_.dir};
  }

 private:
  Vec3 p_;
  double best_d2_ = kInf, along_ = 0;
  PolylineSegment best_;
};
}  // namespace

CentrelineProjection ProjectPointOntoPolyline(const std::vector<Vec3>& polyline, const Vec3& p) {
  NearestOnPolyline nearest(p);
  ForEachSegment(polyline, [&](const PolylineSegment& s) { nearest.Offer(s); });
  return nearest.Result();
}

Expected<std::vector<CentrelineProjection>> ProjectOntoPolyline(const std::vector<Vec3>& points,
                                                                const std::vector<Vec3>& polyline) {
  if (polyline.size() < 2)
    return InvalidArgument("centreline", "centreline needs at least 2 points");
  for (size_t i = 0; i + 1 < polyline.size(); ++i) {
    if (!((polyline[i + 1] - polyline[i]).norm() > 0)) {
      return InvalidArgument(
          "centreline", "centreline point " + std::to_string(i + 1) + " repeats the one before it");
    }
  }
  // The segments made once for every point (not a square root and a division per segment and
  // point).
  std::vector<PolylineSegment> segments;
  ForEachSegment(polyline, [&](const PolylineSegment& s) { segments.push_back(s); });
  std::vector<CentrelineProjection> out(points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    NearestOnPolyline nearest(points[k]);
    for (const PolylineSegment& s : segments) nearest.Offer(s);
    out[k] = nearest.Result();
  }
  return out;
}

Expected<SurfacePoint> ClosestSurfacePoint(const TriMesh& mesh, const Vec3& p) {
  if (mesh.triangles.empty()) return InvalidArgument("mesh", "mesh has no triangles");
  if (!p.allFinite()) return InvalidArgument("point", "query point is not finite");
  SurfacePoint best;
  double best_d2 = kInf;
  for (int f = 0; f < mesh.TriangleCount(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const Vec3 w =
        ClosestPointOnTriangle(p, mesh.positions[t[0]], mesh.positions[t[1]], mesh.positions[t[2]]);
    const Vec3 c =
        w[0] * mesh.positions[t[0]] + w[1] * mesh.positions[t[1]] + w[2] * mesh.positions[t[2]];
    const double d2 = (c - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = SurfacePoint{f, w};
    }
  }
  return best;
}

Vec3 PositionOf(const TriMesh& mesh, const SurfacePoint& sp) {
  const Triangle& t = mesh.triangles[sp.triangle];
  return sp.barycentric[0] * mesh.positions[t[0]] + sp.barycentric[1] * mesh.positions[t[1]] +
         sp.barycentric[2] * mesh.positions[t[2]];
}

Vec3 NormalOf(const TriMesh& mesh, const SurfacePoint& sp) {
  return TriangleNormal(mesh, sp.triangle);
}

Expected<std::vector<double>> GeodesicDistances(const TriMesh& mesh, const SurfacePoint& source,
                                                GeodesicMethod method) {
  if (Status s = Validate(mesh); !s.ok()) return s.error();
  if (source.triangle < 0 || source.triangle >= mesh.TriangleCount()) {
    return InvalidArgument("source", "source triangle is out of range");
  }
  if (!source.barycentric.allFinite() || std::abs(source.barycentric.sum() - 1.0) > 1e-6 ||
      source.barycentric.minCoeff() < -1e-9) {
    return InvalidArgument("source", "source barycentric weights must be ≥ 0 and sum to 1");
  }
  const VertexAdjacency adj = BuildVertexAdjacency(mesh);
  std::vector<double> dijkstra = DijkstraFrom(mesh, adj, Seeds(mesh, source));
  if (method == GeodesicMethod::kDijkstra) return dijkstra;
  return HeatFrom(mesh, source, dijkstra);
}

}  // namespace vsurg::geometry
