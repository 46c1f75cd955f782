#include "common/geometry/cgal_mesh.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_polyhedron_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/make_mesh_3.h>

#include <array>
#include <cstdio>
#include <iterator>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace vsurg::geometry::cgal {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Polyhedron = CGAL::Mesh_polyhedron_3<K>::type;
using Domain = CGAL::Polyhedral_mesh_domain_3<Polyhedron, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

}  // namespace

Expected<TetMesh> MeshClosedSurface(const TriMesh& surface, double size, double facet_distance,
                                    double radius_edge_ratio) {
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
  Domain domain(poly);
  namespace p = CGAL::parameters;
  Criteria criteria(p::facet_angle = 25, p::facet_size = size, p::facet_distance = facet_distance,
                    p::cell_radius_edge_ratio = radius_edge_ratio, p::cell_size = size);
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
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c)
    out.tetrahedra.push_back(
        {id(c->vertex(0)), id(c->vertex(1)), id(c->vertex(2)), id(c->vertex(3))});
  return out;
}

}  // namespace vsurg::geometry::cgal
