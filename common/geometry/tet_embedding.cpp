#include "common/geometry/tet_embedding.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace vsurg::geometry {
namespace {

// Barycentric weights of p in tetrahedron t (they sum to 1; all ≥ 0 inside).
std::array<double, 4> Barycentric(const TetMesh& mesh, const Tetrahedron& t, const Vec3& p) {
  const Vec3& a = mesh.positions[t[0]];
  Eigen::Matrix3d d;
  d.col(0) = mesh.positions[t[1]] - a;
  d.col(1) = mesh.positions[t[2]] - a;
  d.col(2) = mesh.positions[t[3]] - a;
  const Vec3 w = d.partialPivLu().solve(p - a);
  return {1.0 - w.sum(), w.x(), w.y(), w.z()};
}

struct Grid {
  Vec3 lo;
  double cell = 1;
  std::array<int, 3> n = {1, 1, 1};
  std::vector<std::vector<int>> cells;

  std::array<int, 3> Cell(const Vec3& p) const {
    std::array<int, 3> c;
    for (int k = 0; k < 3; ++k)
      c[k] = std::clamp(static_cast<int>(std::floor((p[k] - lo[k]) / cell)), 0, n[k] - 1);
    return c;
  }
  const std::vector<int>& At(int i, int j, int k) const {
    return cells[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
  }
};

Grid BuildGrid(const TetMesh& mesh) {
  Grid g;
  Vec3 lo = mesh.positions[0], hi = lo;
  for (const Vec3& p : mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const Vec3 size = (hi - lo).cwiseMax(1e-9);
  // About two elements per cell: cell volume ≈ 2 × the mean element's box.
  const double volume = size.prod();
  g.cell = std::max(1e-9, std::cbrt(2.0 * volume / std::max(1, mesh.TetCount())));
  for (int k = 0; k < 3; ++k)
    g.n[k] = std::clamp(static_cast<int>(std::ceil(size[k] / g.cell)), 1, 256);
  g.lo = lo;
  g.cell = std::max({size.x() / g.n[0], size.y() / g.n[1], size.z() / g.n[2]});
  g.cells.resize(static_cast<size_t>(g.n[0]) * g.n[1] * g.n[2]);
  for (int t = 0; t < mesh.TetCount(); ++t) {
    Vec3 a = mesh.positions[mesh.tetrahedra[t][0]], b = a;
    for (int v : mesh.tetrahedra[t])
      a = a.cwiseMin(mesh.positions[v]), b = b.cwiseMax(mesh.positions[v]);
    const auto c0 = g.Cell(a), c1 = g.Cell(b);
    for (int k = c0[2]; k <= c1[2]; ++k)
      for (int j = c0[1]; j <= c1[1]; ++j)
        for (int i = c0[0]; i <= c1[0]; ++i)
          g.cells[(static_cast<size_t>(k) * g.n[1] + j) * g.n[0] + i].push_back(t);
  }
  return g;
}

}  // namespace

Expected<std::vector<EmbeddedPoint>> EmbedPoints(const TetMesh& mesh,
                                                 const std::vector<Vec3>& points) {
  if (mesh.TetCount() == 0) return InvalidArgument("mesh", "no tetrahedra to embed points in");
  if (Status s = Validate(mesh, 0.0); !s.ok()) return s.error();
  const Grid g = BuildGrid(mesh);
  std::vector<EmbeddedPoint> out(points.size());
  std::vector<int> seen(mesh.TetCount(), -1);
  for (size_t q = 0; q < points.size(); ++q) {
    const Vec3& p = points[q];
    if (!p.allFinite())
      return InvalidArgument("points", "point " + std::to_string(q) + " is not finite");
    EmbeddedPoint best;
    best.distance = std::numeric_limits<double>::infinity();
    // The point's cell (clamped into the grid) and its distance outside the grid's box.
    const auto c = g.Cell(p);
    const Vec3 hi = g.lo + g.cell * Vec3(g.n[0], g.n[1], g.n[2]);
    const double outside_box = (p - p.cwiseMax(g.lo).cwiseMin(hi)).norm();
    const int max_ring = std::max({g.n[0], g.n[1], g.n[2]});
    for (int ring = 0; ring <= max_ring; ++ring) {
      // Every element in a ring ≥ r is at least (r − 1)·cell + outside_box away.
      if (best.distance == 0 || (ring > 0 && (ring - 1) * g.cell + outside_box > best.distance))
        break;
      for (int k = c[2] - ring; k <= c[2] + ring; ++k)
        for (int j = c[1] - ring; j <= c[1] + ring; ++j)
          for (int i = c[0] - ring; i <= c[0] + ring; ++i) {
            if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) != ring)
              continue;  // only the ring's shell
            if (i < 0 || j < 0 || k < 0 || i >= g.n[0] || j >= g.n[1] || k >= g.n[2]) continue;
            for (int t : g.At(i, j, k)) {
              if (seen[t] == static_cast<int>(q)) continue;
              seen[t] = static_cast<int>(q);
              std::array<double, 4> w = Barycentric(mesh, mesh.tetrahedra[t], p);
              double sum = 0;
              for (double& x : w) sum += (x = std::max(0.0, x));
              for (double& x : w) x /= sum;
              Vec3 nearest = Vec3::Zero();
              for (int a = 0; a < 4; ++a) nearest += w[a] * mesh.positions[mesh.tetrahedra[t][a]];
              const double d = (p - nearest).norm();
              if (d < best.distance - 1e-15) {
                best.tet = t;
                best.vertices = mesh.tetrahedra[t];
                best.weights = w;
                best.distance = d < 1e-12 ? 0.0 : d;
              }
            }
          }
    }
    out[q] = best;
  }
  return out;
}

}  // namespace vsurg::geometry
