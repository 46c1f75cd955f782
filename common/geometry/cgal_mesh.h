// The CGAL side of Tetrahedralize (tetrahedralize.h), in a translation unit of its own: CGAL's
// Mesh_3 templates are most of the project's heaviest unit to compile, and common/CMakeLists.txt
// builds this one at -O1 without debug lines and, in the sanitizer builds, without
// instrumentation (CGAL is a well-kept library, not our code; everything of ours around the call
// stays in tetrahedralize.cpp and keeps every check).
#pragma once

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry::cgal {

// The surface as CGAL's polyhedron, refused when CGAL cannot stitch it closed or two of its
// triangles cross (named by their centroids); then Mesh_3 to the criteria (facet angle ≥ 25°,
// facet size and cell size `size`, surface distance `facet_distance`, the radius–edge ratio),
// without perturbation and with exudation. The result's vertices and tetrahedra are the
// triangulation's, each tetrahedron as CGAL orders it (the caller orients them).
Expected<TetMesh> MeshClosedSurface(const TriMesh& surface, double size, double facet_distance,
                                    double radius_edge_ratio);

}  // namespace vsurg::geometry::cgal
