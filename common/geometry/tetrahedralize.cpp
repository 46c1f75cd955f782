#include "common/geometry/tetrahedralize.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_polyhedron_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/make_mesh_3.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace vsurg::geometry {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Polyhedron = CGAL::Mesh_polyhedron_3<K>::type;
using Domain = CGAL::Polyhedral_mesh_domain_3<Polyhedron, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

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
  std::vector<K::Point_3> points;
  points.reserve(surface.positions.size());
  for (const Vec3& p : surface.positions) points.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::array<std::size_t, 3>> faces;
  for (const Triangle& t : surface.triangles)
    faces.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]),
                     static_cast<std::size_t>(t[2])});
  Polyhedron poly;
  CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points, faces, poly);
  if (!CGAL::is_closed(poly))
    return InvalidArgument("surface", "not closed (CGAL could not stitch it into a closed mesh)");
  std::vector<std::pair<Polyhedron::Facet_const_handle, Polyhedron::Facet_const_handle>> crossing;
  CGAL::Polygon_mesh_processing::self_intersections(poly, std::back_inserter(crossing));
  if (!crossing.empty()) {
    // Name the first pair by their centroids (the polyhedron does not keep our indices).
    auto centre = [](Polyhedron::Facet_const_handle f) {
      auto h = f->facet_begin();
      Vec3 c = Vec3::Zero();
      int n = 0;
      do {
        const auto& p = h->vertex()->point();
        c += Vec3(p.x(), p.y(), p.z());
        ++n;
      } while (++h != f->facet_begin());
      return Vec3(c / n);
    };
    const Vec3 a = centre(crossing[0].first), b = centre(crossing[0].second);
    char where[160];
    std::snprintf(where, sizeof where, "(%.4g, %.4g, %.4g) and (%.4g, %.4g, %.4g)", a.x(), a.y(),
                  a.z(), b.x(), b.y(), b.z());
    return InvalidArgument("surface", "intersects itself: " + std::to_string(crossing.size()) +
                                          " pairs of triangles cross, e.g. those centred at " +
                                          where + " (m)");
  }
  Vec3 lo = surface.positions[0], hi = lo;
  for (const Vec3& p : surface.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double size = params.size > 0 ? params.size : (hi - lo).norm() / 12.0;
  const double distance = params.facet_distance > 0 ? params.facet_distance : size / 8.0;
  if (!std::isfinite(size) || !(size > 0) || !(params.radius_edge_ratio >= 2.0))
    return InvalidArgument("size", "the element size must be > 0 and the radius-edge ratio >= 2");
  Domain domain(poly);
  namespace p = CGAL::parameters;
  Criteria criteria(p::facet_angle = 25, p::facet_size = size, p::facet_distance = distance,
                    p::cell_radius_edge_ratio = params.radius_edge_ratio, p::cell_size = size);
  const C3t3 c3t3 =
      CGAL::make_mesh_3<C3t3>(domain, criteria, p::no_perturb(), p::exude(p::sliver_bound = 10));

  TetMesh out;
  std::map<Tr::Vertex_handle, int> index;
  auto id = [&](Tr::Vertex_handle v) {
    auto [it, inserted] = index.try_emplace(v, out.VertexCount());
    if (inserted) {
      const auto& q = v->point().point();
      out.positions.emplace_back(q.x(), q.y(), q.z());
    }
    return it->second;
  };
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    Tetrahedron t = {id(c->vertex(0)), id(c->vertex(1)), id(c->vertex(2)), id(c->vertex(3))};
    out.tetrahedra.push_back(t);
    if (TetVolume(out, out.TetCount() - 1) < 0)
      std::swap(out.tetrahedra.back()[2], out.tetrahedra.back()[3]);
  }
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
