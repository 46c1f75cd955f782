#include "common/sim/palpation_case.h"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <limits>

#include "common/sim/rooms/room_support.h"

namespace vsurg::sim {

std::string CaseName(const std::string& scene_name, uint64_t seed) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016" PRIx64, seed);
  return scene_name + ".case-" + hex;
}

std::vector<int> PalpableTriangles(const geometry::TriMesh& rest, const std::vector<int>& held) {
  std::vector<uint8_t> is_held(rest.VertexCount(), 0);
  for (int v : held) is_held[v] = 1;
  std::vector<int> out;
  for (int t = 0; t < rest.TriangleCount(); ++t) {
    const geometry::Triangle& tri = rest.triangles[t];
    if (is_held[tri[0]] || is_held[tri[1]] || is_held[tri[2]]) continue;
    if (geometry::TriangleNormal(rest, t).z() >= 0.5) out.push_back(t);
  }
  return out;
}

std::vector<double> RimDistance(const geometry::TriMesh& rest, const std::vector<int>& palpable) {
  std::vector<uint8_t> inside(rest.TriangleCount(), 0), on_palpable(rest.VertexCount(), 0),
      on_other(rest.VertexCount(), 0);
  for (int t : palpable) inside[t] = 1;
  for (int t = 0; t < rest.TriangleCount(); ++t)
    for (int v : rest.triangles[t]) (inside[t] ? on_palpable : on_other)[v] = 1;
  std::vector<int> rim;
  for (int v = 0; v < rest.VertexCount(); ++v)
    if (on_palpable[v] && on_other[v]) rim.push_back(v);
  std::vector<double> out(rest.VertexCount(), std::numeric_limits<double>::infinity());
  for (int v = 0; v < rest.VertexCount(); ++v)
    for (int r : rim) out[v] = std::min(out[v], (rest.positions[v] - rest.positions[r]).norm());
  return out;
}

// The lumps are drawn under the palpable surface at least the scene's margin from its rim, in the
// FEM the case's contact table is built from.
Expected<Scene> DrawCase(const Scene& scene, uint64_t seed) {
  if (!scene.cases) return scene;
  auto mesh = BuildSceneMesh(scene.mesh);
  if (!mesh.ok()) return mesh.error();
  auto held = SupportedVertices(mesh->surface, scene.region, mesh->groups);
  if (!held.ok()) return held.error();
  auto fem = ReducedFemMesh(scene, mesh->surface);
  if (!fem.ok()) return fem.error();
  const std::vector<int> surface = PalpableTriangles(mesh->surface, *held);
  const std::vector<double> rim = RimDistance(mesh->surface, surface);
  geometry::TriMesh palpable;
  palpable.positions = mesh->surface.positions;
  for (int t : surface) {
    const geometry::Triangle& tri = mesh->surface.triangles[t];
    if (std::min({rim[tri[0]], rim[tri[1]], rim[tri[2]]}) >= scene.case_margin)
      palpable.triangles.push_back(tri);
  }
  if (palpable.triangles.empty())
    return Error{ErrorCode::kInvalidArgument,
                 "no palpable surface lies this far from its rim: a smaller margin_mm",
                 "task.cases.margin_mm"};
  auto lumps = tissue::DrawInclusions(*fem, palpable, *scene.cases, seed);
  if (!lumps.ok())
    return Error{lumps.error().code, lumps.error().message, "task.cases." + lumps.error().field};
  Scene out = scene;
  out.inclusions = std::move(*lumps);
  out.name = CaseName(scene.name, seed);
  return out;
}

}  // namespace vsurg::sim
