// Embedding points in a tetrahedral mesh: each point gets a tetrahedron and its barycentric
// weights, so any field on the mesh's vertices interpolates at the point with the linear
// elements' own shape functions (u(p) = Σ_k w_k·u_k). The reduced models use it to carry a FEM
// mesh's precomputed responses onto the finer display surface the station draws.
//
// A point inside the mesh gets the tetrahedron that contains it (weights in [0, 1], summing to
// 1). A point outside (a smooth display surface bulges past the faceted FEM boundary between
// its vertices) gets the nearest tetrahedron with its weights clamped to [0, 1] and
// renormalised: the field at the nearest point of that element, and `distance` says how far
// that is (m). Search: a uniform grid of the tetrahedra's bounding boxes, rings of cells
// outward from the point's cell until no nearer element can remain. Set-up code: allocates.
#pragma once

#include <array>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

struct EmbeddedPoint {
  int tet = -1;
  std::array<int, 4> vertices = {0, 0, 0, 0};
  std::array<double, 4> weights = {0, 0, 0, 0};  // ≥ 0, sum 1
  double distance = 0;                           // m from the point to the element; 0 inside
};

// Fails (kInvalidArgument) on an empty or invalid mesh or a non-finite point.
Expected<std::vector<EmbeddedPoint>> EmbedPoints(const TetMesh& mesh,
                                                 const std::vector<Vec3>& points);

// Σ_k w_k·field[vertices[k]].
template <class T>
T Interpolate(const EmbeddedPoint& e, const std::vector<T>& field) {
  return e.weights[0] * field[e.vertices[0]] + e.weights[1] * field[e.vertices[1]] +
         e.weights[2] * field[e.vertices[2]] + e.weights[3] * field[e.vertices[3]];
}

}  // namespace vsurg::geometry
