// What the rooms' builds share (private to common/sim): the scene's material for the FEM, the
// FEM mesh of a reduced model, a reduced table's inputs, and one table per scene shared by its
// sessions. Build time only: nothing here runs on the haptic path.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/fem.h"
#include "common/tissue/reduced.h"
#include "common/tissue/reduced_cache.h"

namespace vsurg::sim {

// The scene's tissue as the FEM takes it (E = 2G(1 + ν)).
tissue::FemParams SceneMaterial(const Scene& scene);

// The FEM of a reduced contact or surface-twist model: a tetrahedral ball of the scene sphere's
// radius, or the mesh file's closed surface tetrahedralised (CGAL).
Expected<geometry::TetMesh> ReducedFemMesh(const Scene& scene, const geometry::TriMesh& rest);

// A limb grasp's frame: the axis is the centreline where it passes the grasp, the lever the
// grasp's distance from it (at least the scene's least lever). Haptic thread; no allocation.
GraspFrame LimbGraspFrame(const std::vector<geometry::Vec3>& centreline, const GraspQuery& q);

// A linear twist answer, T = Φ·k up to the capacity (overloaded beyond it): the FEM's twist
// fields (reduced twist, surface twist). k in N·m/rad, capacity in N·m.
TwistAnswer LinearTwist(double twist, double stiffness, double capacity);

// A point of the rest surface given by its triangle and barycentric coordinates.
geometry::Vec3 RestPoint(const geometry::TriMesh& rest, int triangle,
                         const geometry::Vec3& barycentric);

// The scene's material on its FEM mesh: the homogeneous tissue's (SceneMaterial), with each
// element's modulus scaled by the inclusions it holds; refused, naming the inclusion, when one
// lies outside the tissue.
Expected<tissue::FemParams> SceneMaterialOn(const Scene& scene, const geometry::TetMesh& fem);

// A reduced table's inputs for a scene: its FEM held by the scene's support (as the surface's
// `held` vertices are), the display, and every display vertex not held, which a tool can reach.
template <class Params>
Expected<tissue::TableInputs<Params>> TableInputsFor(const Scene& scene,
                                                     const geometry::TriMesh& rest,
                                                     const std::vector<int>& held,
                                                     geometry::TetMesh fem) {
  tissue::TableInputs<Params> in;
  auto material = SceneMaterialOn(scene, fem);
  if (!material.ok()) return material.error();
  in.mesh = std::move(fem);
  in.material = std::move(*material);
  in.fixed = SupportedFemVertices(in.mesh, rest, held, scene.region);
  in.display = rest;
  std::vector<uint8_t> is_held(rest.VertexCount(), 0);
  for (int v : held) is_held[v] = 1;
  for (int v = 0; v < rest.VertexCount(); ++v)
    if (!is_held[v]) in.reachable.push_back(v);
  return in;
}

// Reduced tables (contact and surface twist) are read-only and large (72 and 12 B per vertex
// pair): the sessions of one scene share one, found by the key of its inputs while any session
// holds it. `load` reads it from the cache or builds it; another session of the same scene waits
// for a table being built (and does not build it twice) while other scenes' sessions go on.
// Null (and `status` set) when it cannot be had.
std::shared_ptr<const tissue::ContactResponse> SharedContactTable(
    const std::string& key, const std::function<Expected<tissue::ContactResponse>()>& load,
    Status& status);
std::shared_ptr<const tissue::SurfaceTwistTable> SharedSurfaceTwistTable(
    const std::string& key, const std::function<Expected<tissue::SurfaceTwistTable>()>& load,
    Status& status);

}  // namespace vsurg::sim
