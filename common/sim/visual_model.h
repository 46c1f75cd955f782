// What the station draws for a scene, apart from what the server simulates: the fine visual
// surface carried by the physics surface (common/geometry/visual_surface.h), its material, the
// instrument the task is done with, and the table the tissue rests on.
//
// Built by the station (and the monitor, and the render tests) from the scene file it already
// reads; nothing of it crosses the network. Units: metres.
#pragma once

#include <optional>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/geometry/visual_surface.h"
#include "common/sim/scene.h"

namespace vsurg::sim {

// The instrument: a blunt probe for palpation (press tasks), a grasper whose jaws close with
// the button for a twist anywhere on a surface (forceps), a grip for twisting a limb, a needle
// on a syringe for a needle insertion, a scalpel for a cut.
enum class Instrument { kProbe, kGrasper, kGrip, kNeedle, kScalpel };
const char* InstrumentName(Instrument i);

struct VisualModel {
  geometry::TriMesh surface;         // the fine surface at rest (normals included)
  geometry::SurfaceMapping mapping;  // physics surface → `surface`
  // The physics surface drawn as it is (a cut's patch, whose faces a cut changes: a finer surface
  // mapped over it would not open along the cut): `surface` is the physics surface, `mapping`
  // unused.
  bool physics_drawn = false;
  // The same surface at about a quarter of the triangles (a limb's skin at half the vertices
  // around and along, an organ refined one level less), for the levels a software renderer draws
  // (client::Quality below high): silhouettes stay within a fraction of a pixel at the station's
  // size; the per-vertex tone and vessels are sampled a little coarser. Empty for an imported
  // visual mesh (drawn at every level as is).
  geometry::TriMesh coarse_surface;
  geometry::SurfaceMapping coarse_mapping;  // physics surface → `coarse_surface`
  VisualMaterial material = VisualMaterial::kSkin;
  Instrument instrument = Instrument::kProbe;
  // Two hands: the second hand's instrument (a cut scene's grasper), drawn where the station's
  // second device is; unset when the scene has one tool.
  std::optional<Instrument> second_instrument;
  // A cut scene's marked pattern (the line or circle to cut along), as points on the patch at
  // rest (m); the view draws it on the tissue as it moves. Empty for the other scenes.
  std::vector<Eigen::Vector3d> marked_line;
  // A cut scene's sheet thickness (m): the height of the walls a cut opens, drawn in the
  // tissue's interior colour. 0 for the other scenes.
  double sheet_thickness = 0;
  // The table under the tissue: its upward normal (the world's up) and its height along it.
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  double table_height = 0;  // m, along `up`
  // The twist task's axis and the point on it where the instrument holds (a limb: its distal
  // end); the target arc is drawn there. Zero for a press task.
  Eigen::Vector3d twist_axis = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d twist_centre = Eigen::Vector3d::Zero();
  double twist_radius = 0;  // m, the arc's radius
};

// `physics` is the scene's physics surface at rest (BuildSceneMesh(scene.mesh).surface).
Expected<VisualModel> BuildVisualModel(const Scene& scene, const geometry::TriMesh& physics);

}  // namespace vsurg::sim
