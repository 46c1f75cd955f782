// Triangle and tetrahedral meshes: plain data plus the few queries every model needs.
//
// Units: metres. Triangles are counter-clockwise seen from outside (outward normals by the
// right-hand rule); tetrahedra (a, b, c, d) have positive volume, i.e. (b−a)×(c−a)·(d−a) > 0.
// Meshes are built once (generators, OBJ import) and then only their positions change, so the
// connectivity queries below allocate and are meant for set-up, never for the haptic loop.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products on Vec3 everywhere the type is used

#include "common/core/expected.h"

namespace vsurg::geometry {

using Vec3 = Eigen::Vector3d;
using Triangle = std::array<int, 3>;
using Tetrahedron = std::array<int, 4>;

struct TriMesh {
  std::vector<Vec3> positions;      // m
  std::vector<Triangle> triangles;  // indices into positions, counter-clockwise from outside
  std::vector<Vec3> normals;        // per vertex, unit; empty until ComputeVertexNormals

  int VertexCount() const { return static_cast<int>(positions.size()); }
  int TriangleCount() const { return static_cast<int>(triangles.size()); }
};

struct TetMesh {
  std::vector<Vec3> positions;          // m
  std::vector<Tetrahedron> tetrahedra;  // positive orientation (see above)

  int VertexCount() const { return static_cast<int>(positions.size()); }
  int TetCount() const { return static_cast<int>(tetrahedra.size()); }
};

// Indices in range, positions finite, no triangle that repeats a vertex. A zero-area triangle
// with distinct vertices is allowed (it occurs in imported scans); models that divide by area
// must check for themselves.
Status Validate(const TriMesh& mesh);

// Indices in range, positions finite, every tetrahedron of volume > min_volume (m³). An
// inverted or flat element is named with its index in the error.
Status Validate(const TetMesh& mesh, double min_volume = 0.0);

// Area-weighted vertex normals, unit length; an isolated vertex gets (0, 0, 0).
void ComputeVertexNormals(TriMesh& mesh);

// Unit normal of triangle t (zero for a degenerate one); its area.
Vec3 TriangleNormal(const TriMesh& mesh, int t);
// The normal over any positions (a deformed snapshot of the mesh).
Vec3 TriangleNormal(const std::vector<Vec3>& positions, const Triangle& t);
// A unit vector perpendicular to `a` (nonzero), with no other choice made: a frame's first axis.
Vec3 AnyPerpendicular(const Vec3& a);
double TriangleArea(const TriMesh& mesh, int t);

// Compressed vertex→vertex adjacency (the one-ring), neighbours sorted ascending.
struct VertexAdjacency {
  std::vector<int> offsets;     // size V+1
  std::vector<int> neighbours;  // neighbours of v are [offsets[v], offsets[v+1])

  int Degree(int v) const { return offsets[v + 1] - offsets[v]; }
};
VertexAdjacency BuildVertexAdjacency(const TriMesh& mesh);

// Unique undirected edges (i < j), sorted.
std::vector<std::array<int, 2>> UniqueEdges(const TriMesh& mesh);

// Topology report: a closed, consistently oriented 2-manifold has every undirected edge in
// exactly two triangles that traverse it in opposite directions.
struct TopologyReport {
  int boundary_edges = 0;        // edges used by one triangle
  int non_manifold_edges = 0;    // edges used by three or more triangles
  int misoriented_edges = 0;     // edges two triangles traverse in the same direction
  int euler_characteristic = 0;  // V − E + F
  bool Closed() const { return boundary_edges == 0 && non_manifold_edges == 0; }
  bool ConsistentlyOriented() const { return misoriented_edges == 0; }
};
TopologyReport CheckTopology(const TriMesh& mesh);

// Signed enclosed volume (m³) by the divergence theorem; positive for an outward-oriented
// closed mesh.
double SignedVolume(const TriMesh& mesh);

// Signed volume of one tetrahedron (m³).
double TetVolume(const TetMesh& mesh, int t);

// The faces used by exactly one tetrahedron, oriented outward, as a surface mesh over the same
// positions (unused vertices are kept so indices match the tetrahedral mesh).
TriMesh BoundarySurface(const TetMesh& mesh);

}  // namespace vsurg::geometry
