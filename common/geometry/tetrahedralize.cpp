#include "common/geometry/tetrahedralize.h"

#include "common/geometry/cgal_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace vsurg::geometry {
namespace {

// The dihedral angles of tetrahedron (a, b, c, d), degrees.
void Dihedrals(const std::array<Vec3, 4>& x, double& lo, double& hi) {
  static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                       {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  for (const auto& e : kEdges) {
    const Vec3 axis = (x[e[1]] - x[e[0]]).normalized();
    Vec3 u = x[e[2]] - x[e[0]], v = x[e[3]] - x[e[0]];
    u -= u.dot(axis) * axis;
    v -= v.dot(axis) * axis;
    const double angle = std::atan2(u.cross(v).norm(), u.dot(v)) * 180.0 / std::numbers::pi;
    lo = std::min(lo, angle);
    hi = std::max(hi, angle);
  }
}

}  // namespace

Expected<TetMesh> Tetrahedralize(const TriMesh& surface, const TetrahedralizeParams& params,
                                 TetQuality* quality) {
  if (Status s = Validate(surface); !s.ok()) return s.error();
  if (surface.triangles.empty()) return InvalidArgument("surface", "no triangles");
  // Closed and consistently oriented: name an offending edge.
  std::map<std::pair<int, int>, int> directed;
  for (const Triangle& t : surface.triangles)
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  for (const auto& [edge, count] : directed)  // two triangles running the same way along it
    if (count > 1)
      return InvalidArgument("surface",
                             "not consistently oriented (or not a manifold) at the "
                             "edge between vertices " +
                                 std::to_string(edge.first) + " and " +
                                 std::to_string(edge.second));
  for (const auto& [edge, count] : directed)
    if (!directed.count({edge.second, edge.first}))
      return InvalidArgument("surface", "not closed: the edge between vertices " +
                                            std::to_string(edge.first) + " and " +
                                            std::to_string(edge.second) +
                                            " belongs to one triangle only (a hole)");
  Vec3 lo = surface.positions[0], hi = lo;
  for (const Vec3& p : surface.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double size = params.size > 0 ? params.size : (hi - lo).norm() / 12.0;
  const double distance = params.facet_distance > 0 ? params.facet_distance : size / 8.0;
  if (!std::isfinite(size) || !(size > 0) || !(params.radius_edge_ratio >= 2.0))
    return InvalidArgument("size", "the element size must be > 0 and the radius-edge ratio >= 2");
  auto meshed = cgal::MeshClosedSurface(surface, size, distance, params.radius_edge_ratio);
  if (!meshed.ok()) return meshed.error();
  TetMesh out = std::move(*meshed);
  for (int e = 0; e < out.TetCount(); ++e)  // positively oriented
    if (TetVolume(out, e) < 0) std::swap(out.tetrahedra[e][2], out.tetrahedra[e][3]);
  if (out.tetrahedra.empty())
    return InvalidArgument("size", "no tetrahedra: the element size is larger than the body");
  if (Status s = Validate(out, 0.0); !s.ok()) return s.error();
  if (quality) {
    *quality = TetQuality{};
    quality->tets = out.TetCount();
    quality->vertices = out.VertexCount();
    quality->min_dihedral_deg = 180;
    for (int e = 0; e < out.TetCount(); ++e) {
      quality->volume += TetVolume(out, e);
      const auto& t = out.tetrahedra[e];
      Dihedrals(
          {out.positions[t[0]], out.positions[t[1]], out.positions[t[2]], out.positions[t[3]]},
          quality->min_dihedral_deg, quality->max_dihedral_deg);
    }
  }
  return out;
}

}  // namespace vsurg::geometry
