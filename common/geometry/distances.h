// Distances the coil-spring model measures ρ with (DESIGN.md "Model 1", Geometry).
//
// Limb mode: ρ is the distance along the limb centreline from the grasp cross-section, so each
// point is projected onto the centreline polyline. Surface mode: ρ is the geodesic distance on
// the surface from the grasp point, by Dijkstra over mesh edges (exact on the edge graph, an
// over-estimate of the true geodesic by a few percent) or by the heat method (Crane, Weischedel
// & Wardetzky 2013, "Geodesics in heat"), which converges to the true geodesic as the mesh is
// refined. All of this runs at set-up: it allocates and may factorise a sparse matrix.
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

// The closest point of a polyline to a query point.
struct CentrelineProjection {
  double s = 0;                  // arc length of the closest point from the first vertex, m
  Vec3 point = Vec3::Zero();     // the closest point on the polyline
  Vec3 tangent = Vec3::UnitZ();  // unit direction of the segment it lies on
};

// Arc length of each polyline vertex (size = polyline size; first is 0).
std::vector<double> ArcLengths(const std::vector<Vec3>& polyline);

// One point (no allocation; any thread): zero-length segments are skipped.
CentrelineProjection ProjectPointOntoPolyline(const std::vector<Vec3>& polyline, const Vec3& p);

// Projects every point onto the polyline (at least two distinct vertices). Brute force over
// segments: O(points × segments), fine at set-up for limbs of a few hundred rings.
Expected<std::vector<CentrelineProjection>> ProjectOntoPolyline(const std::vector<Vec3>& points,
                                                                const std::vector<Vec3>& polyline);

// A point on a surface: a triangle and barycentric weights (w0 + w1 + w2 = 1).
struct SurfacePoint {
  int triangle = -1;
  Vec3 barycentric = Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);
};

// The surface point closest to p (brute force; set-up only). Fails on a mesh without triangles.
Expected<SurfacePoint> ClosestSurfacePoint(const TriMesh& mesh, const Vec3& p);
Vec3 PositionOf(const TriMesh& mesh, const SurfacePoint& sp);
Vec3 NormalOf(const TriMesh& mesh, const SurfacePoint& sp);  // the triangle's unit normal

enum class GeodesicMethod { kDijkstra, kHeat };

// Geodesic distance (m) from `source` to every vertex. Vertices in another connected component
// get +infinity.
Expected<std::vector<double>> GeodesicDistances(const TriMesh& mesh, const SurfacePoint& source,
                                                GeodesicMethod method);

}  // namespace vsurg::geometry
