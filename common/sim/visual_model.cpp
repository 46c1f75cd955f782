#include "common/sim/visual_model.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/geometry/mesh_import.h"

namespace vsurg::sim {

const char* InstrumentName(Instrument i) {
  switch (i) {
    case Instrument::kProbe:
      return "probe";
    case Instrument::kGrasper:
      return "grasper";
    case Instrument::kGrip:
      return "grip";
    case Instrument::kNeedle:
      return "needle";
    case Instrument::kScalpel:
      return "scalpel";
  }
  return "probe";
}

Expected<VisualModel> BuildVisualModel(const Scene& scene, const geometry::TriMesh& physics) {
  if (physics.positions.empty() || physics.triangles.empty())
    return InvalidArgument("mesh", "the physics surface is empty");
  VisualModel v;
  v.material = scene.visual.material;
  const bool limb = scene.mesh.kind == MeshKind::kLimb;
  if (!scene.visual.mesh.empty()) {
    auto fine = geometry::ImportSurfaceMesh(scene.visual.mesh, scene.visual.metres_per_unit);
    if (!fine.ok()) return Error{fine.error().code, fine.error().message, "visual.mesh"};
    v.surface = std::move(*fine);
    if (v.surface.normals.size() != v.surface.positions.size())
      geometry::ComputeVertexNormals(v.surface);
  } else if (limb) {
    // The skin at about the scene's resolution target: sides of around × along vertices with
    // around : along as the limb's circumference to its length.
    const geometry::LimbParams& p = scene.mesh.limb;
    const double circumference = std::numbers::pi * (p.radius_proximal + p.radius_distal);
    const double aspect = p.length / circumference;
    const int vertices = scene.visual.min_triangles / 2 + 1;
    const int around = std::clamp(static_cast<int>(std::sqrt(vertices / aspect)), 24, 1024);
    const int along = std::clamp(vertices / around + 1, 8, 4096);
    auto skin = geometry::MakeLimbSkin(p, around, along);
    if (!skin.ok()) return skin.error();
    v.surface = std::move(*skin);
    // A quarter of the triangles: half the vertices around and along.
    auto coarse = geometry::MakeLimbSkin(p, std::max(24, around / 2), std::max(8, along / 2));
    if (!coarse.ok()) return coarse.error();
    v.coarse_surface = std::move(*coarse);
  } else if (scene.mesh.kind == MeshKind::kMembrane) {
    v.surface = physics;
    geometry::ComputeVertexNormals(v.surface);
    v.physics_drawn = true;
    v.sheet_thickness = scene.mesh.membrane.thickness;
  } else {
    int levels = 0;
    while (levels < 4 && physics.TriangleCount() << (2 * levels) < scene.visual.min_triangles)
      ++levels;
    v.surface = geometry::PhongRefine(physics, levels);
    if (levels > 0) v.coarse_surface = geometry::PhongRefine(physics, levels - 1);
  }
  if (!v.physics_drawn) v.mapping = geometry::SurfaceMapping::Build(physics, v.surface.positions);
  if (!v.coarse_surface.positions.empty())
    v.coarse_mapping = geometry::SurfaceMapping::Build(physics, v.coarse_surface.positions);
  // A limb lies along z with its back (+y) up; everything else rests on its bottom (−z).
  v.up = limb ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  double lowest = 1e30;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = -lo;
  for (const auto& q : physics.positions) {
    lowest = std::min(lowest, q.dot(v.up));
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  // A cut's patch is held in a frame above the table (the blade goes through it).
  v.table_height = scene.mesh.kind == MeshKind::kMembrane ? lowest - 0.04 : lowest;
  if (scene.task.kind == scoring::TaskKind::kInsert) {
    v.instrument = Instrument::kNeedle;
  } else if (scene.task.kind == scoring::TaskKind::kCut) {
    v.instrument = Instrument::kScalpel;
    if (scene.cut && scene.cut->grasper) v.second_instrument = Instrument::kGrasper;
    if (scene.cut) {
      constexpr int kPoints = 160;  // 0.6 mm apart on the 30 mm circle
      for (int i = 0; i <= kPoints; ++i) {
        double x = 0, y = 0;
        scene.cut->pattern.At(static_cast<double>(i) / kPoints, x, y);
        v.marked_line.emplace_back(x, y, 0.0);
      }
    }
  } else if (scene.task.kind == scoring::TaskKind::kPress ||
             scene.task.kind == scoring::TaskKind::kPalpate) {
    v.instrument = Instrument::kProbe;
  } else if (limb) {
    v.instrument = Instrument::kGrip;
    v.twist_axis = Eigen::Vector3d::UnitZ();
    v.twist_centre = Eigen::Vector3d(0, 0, scene.mesh.limb.length - 0.015);
    v.twist_radius = scene.mesh.limb.radius_distal * 1.25;
  } else {
    // Forceps on an organ: the twist about the surface normal where they hold; the arc is
    // drawn at the grasp (the renderer places it at the instrument), sized to the jaws.
    v.instrument = Instrument::kGrasper;
    v.twist_axis = Eigen::Vector3d::UnitZ();
    v.twist_centre = Eigen::Vector3d(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), hi.z());
    v.twist_radius = std::max(0.012, scene.region.reduced.jaw_radius * 1.6);
  }
  return v;
}

}  // namespace vsurg::sim
