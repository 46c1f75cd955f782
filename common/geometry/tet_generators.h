// Tetrahedral meshes for the FEM reference (DESIGN.md "Model 3").
//
// Tapered cylinder (the limbs and the Saint-Venant test bar): a cross-section disc of concentric
// rings (ring k has 6k vertices around a centre vertex), triangulated between neighbouring rings,
// stacked in layers along z with the radius interpolated linearly from base to tip, each
// triangular prism split into three tetrahedra. The split takes, on every quad face, the
// diagonal from the lower-numbered bottom vertex to the higher-numbered top vertex, so two
// prisms sharing a face cut it the same way and the mesh is conforming.
//
// Ball (sphere palpation): a cube grid mapped onto the ball by the concentric map
// x ↦ R·x·‖x‖∞/‖x‖₂, every cube split into six tetrahedra around a main diagonal (Kuhn), cubes
// mirrored by index parity so the diagonals alternate (isotropic on average) and neighbours cut
// their shared face alike (conforming).
//
// Box: the ball's grid without the map.
//
// All reject parameters that would make degenerate elements, and orient every tetrahedron
// positively (Validate passes with min_volume > 0).
#pragma once

#include <array>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

struct TetCylinderParams {
  double length = 0.25;       // m, along +z from z = 0
  double radius_base = 0.04;  // m at z = 0
  double radius_tip = 0.03;   // m at z = length
  int rings = 4;              // concentric rings in the cross-section (≥ 1)
  int layers = 20;            // element layers along z (≥ 1)
};

struct TetCylinder {
  TetMesh mesh;
  std::vector<int> base;         // vertices on z = 0
  std::vector<int> tip;          // vertices on z = length
  std::vector<double> tip_area;  // m², each tip vertex's share of the end face (a third of
                                 // each adjacent triangle): weights for end tractions
  TetCylinderParams params;
};

Expected<TetCylinder> MakeTetCylinder(const TetCylinderParams& p);

// A tapered cylinder meshed for torsion: linear tetrahedra need thin slices when twisted, about
// three element layers per mean radius of length for each ring of the cross-section.
TetCylinderParams TorsionCylinder(double length, double radius_base, double radius_tip, int rings);

struct TetBallParams {
  double radius = 0.05;  // m
  int cells = 8;         // cube cells per axis (even, ≥ 2)
};

Expected<TetMesh> MakeTetBall(const TetBallParams& p);

// Box (a palpation pad, breast-like tissue on a table): the same Kuhn grid, uniform, x and y
// centred on 0, z from 0 (the table) to the height.
struct TetBoxParams {
  Vec3 size = Vec3(0.12, 0.12, 0.04);  // m
  std::array<int, 3> cells = {20, 20, 8};
};
Expected<TetMesh> MakeTetBox(const TetBoxParams& p);

// The boundary of a tetrahedral mesh as a surface of its own vertices only (BoundarySurface
// keeps the interior ones): `fem_vertex[v]` is surface vertex v's index in `mesh`.
TriMesh CompactBoundarySurface(const TetMesh& mesh, std::vector<int>* fem_vertex = nullptr);

}  // namespace vsurg::geometry
