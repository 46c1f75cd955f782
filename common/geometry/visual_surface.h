// The visual model apart from the mechanical one (SOFA's mapping idea): a fine surface that only
// the screen sees, carried by the coarse physics surface that the server simulates.
//
// The station receives the physics surface's moved vertices (nothing else crosses the network)
// and computes the fine surface from them through a SurfaceMapping built once at rest:
//
//   each fine vertex p is anchored to a physics triangle (a, b, c) by point-normal projection:
//     p = x(b) + d·n(b)     x(b) = b₀·a + b₁·b + b₂·c, n(b) = b₀·n_a + b₁·n_b + b₂·n_c
//   (b the barycentric weights, Σb = 1, all ≥ 0; n the unit vertex normals, interpolated and
//   not normalised), solved by Newton's method on the closest triangle and walked across edges
//   until the weights are inside one; after the physics surface moves, the same (b, d) give p′
//   from a′, b′, c′ and their new vertex normals. Where no triangle's normal line passes
//   through p (outside a sharp rim), p keeps its closest point and the rest of the offset in
//   that face's frame (e₁ along an edge, e₂ = n_f × e₁): p = x(b) + t₁·e₁ + t₂·e₂ + d·n(b).
//
// Properties (tests/common/geometry/visual_surface_test.cpp): at rest p′ = p (to float
// precision); a rigid motion of the physics surface moves every fine vertex by that same motion
// (vertex normals and face frames turn with it); the anchor uses only vertex data, continuous
// across the physics mesh's edges, so a twist opens no seam; and no offset lies in a face's
// plane, where a sheared face (a twisted limb's surface shears by several degrees) would turn
// it.
//
// Units: metres. Threads: built once; Apply is const and allocation-free after the first call.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/geometry/mesh_generators.h"

namespace vsurg::geometry {

// A smooth fine surface over a coarse one: each triangle split in four `levels` times, every
// new vertex placed by Phong tessellation (Boubekeur & Alexa, SIGGRAPH Asia 2008) with shape
// factor `alpha`. The fine surface passes through every coarse vertex and follows the coarse
// vertex normals between them, so an organ's facets read as a smooth surface that still touches
// the instrument where the physics does. Written here rather than taken from CGAL's subdivision
// methods because those move the coarse vertices (Loop) and would put CGAL's 80 s translation
// unit into the station's build for 60 lines over our own TriMesh.
TriMesh PhongRefine(const TriMesh& coarse, int levels, double alpha = 0.75);

// A forearm's skin at visual resolution: the limb's taper (the physics surface's) with the
// relief a tube lacks, as offsets of the radius (all within a few millimetres, so the anchor of
// every fine vertex is the physics triangle under it): the flexor and extensor muscle bellies
// over the proximal half, the olecranon at the elbow, a wrist flattened front to back with the
// ulnar styloid, and the ends rounded in. `around` × `along` vertices on the sides (the
// forearm's 6 k-vertex physics surface is carried by 160 × 220 = 35 k vertices, 70 k triangles).
Expected<TriMesh> MakeLimbSkin(const LimbParams& limb, int around = 160, int along = 220);

class SurfaceMapping {
 public:
  SurfaceMapping() = default;
  // `coarse` at rest (its normals are computed if missing); `fine_rest` the visual vertices.
  static SurfaceMapping Build(const TriMesh& coarse, const std::vector<Vec3>& fine_rest);

  // The fine vertices for the physics surface at `coarse_positions` with its vertex normals
  // `coarse_normals` (unit, as ComputeVertexNormals gives them). `fine` is resized to
  // fine_count(). Non-finite input vertices leave their fine vertices at the last value.
  void Apply(const std::vector<Vec3>& coarse_positions, const std::vector<Vec3>& coarse_normals,
             std::vector<Eigen::Vector3f>& fine) const;

  size_t fine_count() const { return anchors_.size(); }
  // The largest |t₁|, |t₂| and |d| over all anchors at rest (m): how far the visual surface
  // strays from the physics one.
  double max_tangential_offset() const { return max_tangential_; }
  double max_normal_offset() const { return max_normal_; }
  // Fine vertices anchored by their closest point (with offsets in the face's frame) because no
  // triangle's interpolated normal passes through them (a sharp rim, a fold).
  size_t fallbacks() const { return fallbacks_; }

 private:
  struct Anchor {
    Triangle triangle{};
    float b0 = 0, b1 = 0;  // barycentric weights of the first two corners (b₂ = 1 − b₀ − b₁)
    float t1 = 0, t2 = 0, d = 0;  // m
  };
  std::vector<Anchor> anchors_;
  double max_tangential_ = 0, max_normal_ = 0;
  size_t fallbacks_ = 0;
};

// Per-vertex unit normals of a triangle mesh over `positions` (area-weighted), into `normals`
// (resized); float output for the renderer. A vertex with no area gets `fallback`.
void VertexNormals(const std::vector<Triangle>& triangles,
                   const std::vector<Eigen::Vector3f>& positions,
                   std::vector<Eigen::Vector3f>& normals,
                   const Eigen::Vector3f& fallback = Eigen::Vector3f::UnitZ());

}  // namespace vsurg::geometry
