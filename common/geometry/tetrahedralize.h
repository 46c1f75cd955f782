// Tetrahedral meshes of closed surfaces, by CGAL's Mesh_3 (Debian libcgal-dev): the FEM and the
// reduced models on any anatomy a surface file describes (geometry/mesh_import.h). A
// well-kept library rather than our own: Delaunay refinement with quality guarantees is not our
// core, and CGAL's is the reference implementation.
//
// The surface must be closed (every edge in two triangles), consistently oriented and free of
// self-intersections; anything else is refused with a message that says what is wrong and where
// (a boundary edge's vertices, a pair of intersecting triangles). Mesh_3 then samples the
// surface and refines the interior to the criteria (facet angle ≥ 25°, element size, surface
// distance, radius–edge ratio ≤ 3) without perturbation (slivers exuded), so the result is
// the same on every run. Tetrahedra come out positively oriented; vertices are the triangulation's,
// not the surface's (the display surface is carried by geometry::EmbedPoints).
//
// Cost: set-up only (seconds for tens of thousands of elements); the caller caches the result
// through the reduced models' cache.
#pragma once

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

struct TetrahedralizeParams {
  double size = 0;  // m, the target edge length of facets and cells; 0: 1/12 of the box's diagonal
  double facet_distance = 0;  // m, the largest gap from the input surface; 0: size / 8
  double radius_edge_ratio = 3.0;
};

struct TetQuality {
  int tets = 0, vertices = 0;
  double volume = 0;  // m³
  double min_dihedral_deg = 0, max_dihedral_deg = 0;
};

Expected<TetMesh> Tetrahedralize(const TriMesh& surface, const TetrahedralizeParams& params = {},
                                 TetQuality* quality = nullptr);

}  // namespace vsurg::geometry
