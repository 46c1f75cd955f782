#include "common/sim/rooms/room_support.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>

#include "common/geometry/distances.h"
#include "common/geometry/tet_generators.h"
#include "common/geometry/tetrahedralize.h"

namespace vsurg::sim {

tissue::FemParams SceneMaterial(const Scene& scene) {
  tissue::FemParams p;
  p.poisson = scene.poisson_ratio;
  p.young = 2 * scene.shear_modulus * (1 + scene.poisson_ratio);
  p.density = scene.density;
  p.nodal_volume = scene.volume_at_vertices;
  return p;
}

Expected<tissue::FemParams> SceneMaterialOn(const Scene& scene, const geometry::TetMesh& fem) {
  tissue::FemParams p = SceneMaterial(scene);
  if (scene.inclusions.empty()) return p;
  auto scale = tissue::InclusionStiffnessScale(fem, scene.inclusions);
  if (!scale.ok())
    return Error{scale.error().code, "tissue." + scale.error().message,
                 "tissue." + scale.error().field};
  p.element_stiffness_scale = std::move(*scale);
  return p;
}

Expected<geometry::TetMesh> ReducedFemMesh(const Scene& scene, const geometry::TriMesh& rest) {
  const RegionSpec& region = scene.region;
  if (scene.mesh.kind == MeshKind::kSphere)
    return geometry::MakeTetBall({scene.mesh.radius, region.reduced.fem_cells});
  if (scene.mesh.kind == MeshKind::kBlock) return geometry::MakeTetBox(scene.mesh.block);
  auto fem = geometry::Tetrahedralize(rest, {region.reduced.fem_size, 0, 3.0});
  if (!fem.ok())
    return Error{fem.error().code, scene.mesh.path + ": " + fem.error().message, "mesh"};
  return fem;
}

GraspFrame LimbGraspFrame(const std::vector<geometry::Vec3>& centreline, const GraspQuery& q) {
  const geometry::CentrelineProjection on_axis =
      geometry::ProjectPointOntoPolyline(centreline, q.point);
  GraspFrame f;
  f.axis_point = on_axis.point;
  f.axis = on_axis.tangent;
  f.lever = std::max(q.min_lever, (q.point - f.axis_point).norm());
  return f;
}

TwistAnswer LinearTwist(double twist, double stiffness, double capacity) {
  const double torque = twist * stiffness;
  const bool overload = std::abs(torque) > capacity;
  return {std::clamp(torque, -capacity, capacity), overload ? 0.0 : stiffness, overload};
}

geometry::Vec3 RestPoint(const geometry::TriMesh& rest, int triangle,
                         const geometry::Vec3& barycentric) {
  const geometry::Triangle& t = rest.triangles[triangle];
  return barycentric[0] * rest.positions[t[0]] + barycentric[1] * rest.positions[t[1]] +
         barycentric[2] * rest.positions[t[2]];
}

namespace {

// One map per table type. The map's lock is held only to look up; a table being built holds its
// own key's lock.
template <class Table>
std::shared_ptr<const Table> SharedTable(const std::string& key,
                                         const std::function<Expected<Table>()>& load,
                                         Status& status) {
  struct Entry {
    std::weak_ptr<const Table> table;
    std::shared_ptr<std::mutex> building = std::make_shared<std::mutex>();
  };
  static std::mutex mutex;
  static std::map<std::string, Entry> tables;
  std::shared_ptr<std::mutex> building;
  {
    std::lock_guard<std::mutex> lock(mutex);
    Entry& e = tables[key];
    if (auto alive = e.table.lock()) return alive;
    building = e.building;
  }
  std::lock_guard<std::mutex> build_lock(*building);
  {
    std::lock_guard<std::mutex> lock(mutex);  // built while this one waited?
    if (auto alive = tables[key].table.lock()) return alive;
  }
  auto table = load();
  if (!table.ok()) {
    status = table.error();
    return nullptr;
  }
  auto shared = std::make_shared<const Table>(std::move(*table));
  std::lock_guard<std::mutex> lock(mutex);
  tables[key].table = shared;
  return shared;
}

}  // namespace

std::shared_ptr<const tissue::ContactResponse> SharedContactTable(
    const std::string& key, const std::function<Expected<tissue::ContactResponse>()>& load,
    Status& status) {
  return SharedTable<tissue::ContactResponse>(key, load, status);
}

std::shared_ptr<const tissue::SurfaceTwistTable> SharedSurfaceTwistTable(
    const std::string& key, const std::function<Expected<tissue::SurfaceTwistTable>()>& load,
    Status& status) {
  return SharedTable<tissue::SurfaceTwistTable>(key, load, status);
}

}  // namespace vsurg::sim
