// A cut scene's parts (scene.h; tissue/cut_membrane.h, haptics/blade.h, scoring/cut.h), shared
// with the pattern-cutting drill's files (cut_drill.h), in people's units:
//
//   "cut": { "tissue":  { "size_mm": [80, 80], "cells": 24, "thickness_mm": 1.2,
//                         "youngs_modulus": 1.18e6, "density": 1100, "pretension": 0.02,
//                         "failure_strain": 0.54 },
//            "blade":   { "toughness": 1700, "angle_deg": 0, "width_mm": 0.3 },
//            "pattern": { "type": "circle", "centre_mm": [0, 0], "radius_mm": 15, "band_mm": 2 }
//                     | { "type": "line", "from_mm": [x, y], "to_mm": [x, y], "band_mm": 2 },
//            "grasper": { "jaw_stiffness": 2000, "reach_mm": 4 } }      (the second hand's;
//            optional)
//
// A scene with a "cut" has the mesh {"type": "membrane"}, the model {"type": "cut-membrane"} and
// the task {"type": "cut"}; each is refused by name without the others. The patch lies in the
// plane z = 0 centred on the origin, its normal +z (the side the blade comes from).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/sim/scene.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

namespace {

constexpr double kDeg = std::numbers::pi / 180;

Status ParseCutTissue(const Reader& r, tissue::CutMembraneParams& p) {
  VSURG_TRY(size, r.NumbersOr("size_mm", 2, 10, 500));
  VSURG_TRY(cells, r.IntegerOr("cells", 32, 4, 128));
  VSURG_TRY(thickness, r.Number("thickness_mm", 0.05, 20));
  VSURG_TRY(modulus, r.NumberOr("youngs_modulus", 1.18e6, 1e3, 1e9));
  VSURG_TRY(density, r.NumberOr("density", 1100, 100, 5000));
  VSURG_TRY(pretension, r.NumberOr("pretension", 0.02, 0.001, 0.3));
  VSURG_TRY(failure, r.NumberOr("failure_strain", 0.54, 0.01, 10));
  if (!size.empty()) p.size_x = size[0] * 1e-3, p.size_y = size[1] * 1e-3;
  p.cells = cells, p.thickness = thickness * 1e-3, p.youngs_modulus = modulus;
  p.density = density, p.pretension = pretension, p.failure_strain = failure;
  return tissue::CheckCutMembrane(p);
}

Status ParseCutBlade(const Reader& r, haptics::BladeParams& b) {
  VSURG_TRY(toughness, r.Number("toughness", 1, 1e6));
  VSURG_TRY(angle, r.NumberOr("angle_deg", 0, 0, 79));
  VSURG_TRY(width, r.Number("width_mm", 0.01, 5));
  b.toughness = toughness, b.angle = angle * kDeg, b.width = width * 1e-3;
  return Status::Ok();
}

Status ParseCutPattern(const Reader& r, scoring::CutPattern& p) {
  VSURG_TRY(type, r.String("type"));
  VSURG_TRY(band, r.NumberOr("band_mm", 2, 0.1, 20));
  p.band = band * 1e-3;
  if (type == "circle") {
    VSURG_TRY(centre, r.NumbersOr("centre_mm", 2, -500, 500));
    VSURG_TRY(radius, r.Number("radius_mm", 2, 250));
    p.kind = scoring::CutPattern::Kind::kCircle;
    if (!centre.empty()) p.cx = centre[0] * 1e-3, p.cy = centre[1] * 1e-3;
    p.radius = radius * 1e-3;
    return Status::Ok();
  }
  if (type != "line") return r.Bad("type", "must be line or circle, got '" + type + "'");
  VSURG_TRY(from, r.NumbersOr("from_mm", 2, -500, 500));
  VSURG_TRY(to, r.NumbersOr("to_mm", 2, -500, 500));
  if (from.empty() || to.empty()) return r.Bad("from_mm", "a line needs from_mm and to_mm");
  p.kind = scoring::CutPattern::Kind::kLine;
  p.ax = from[0] * 1e-3, p.ay = from[1] * 1e-3, p.bx = to[0] * 1e-3, p.by = to[1] * 1e-3;
  if (p.Length() < 2e-3) return r.Bad("to_mm", "the line must be at least 2 mm long");
  return Status::Ok();
}

// The pattern must lie on the patch, a band's width and two cells inside its frame.
Status CheckPatternFits(const tissue::CutMembraneParams& patch, const scoring::CutPattern& p) {
  const double margin = p.band + 2 * patch.size_x / patch.cells;
  const double hx = 0.5 * patch.size_x - margin, hy = 0.5 * patch.size_y - margin;
  for (double u = 0; u <= 1.0; u += 1.0 / 64) {
    double x = 0, y = 0;
    p.At(u, x, y);
    if (std::abs(x) > hx || std::abs(y) > hy)
      return InvalidArgument("pattern", "pattern: must lie inside the patch, " +
                                            std::to_string(margin * 1e3) + " mm from its frame");
  }
  return Status::Ok();
}

}  // namespace

namespace scene_detail {

Status ParseCutParts(const Reader& r, tissue::CutMembraneParams& patch, haptics::BladeParams& blade,
                     scoring::CutPattern& pattern) {
  VSURG_TRY(tissue_r, r.Object("tissue"));
  if (Status st = ParseCutTissue(tissue_r, patch); !st.ok()) return st;
  VSURG_TRY(blade_r, r.Object("blade"));
  if (Status st = ParseCutBlade(blade_r, blade); !st.ok()) return st;
  blade.thickness = patch.thickness;
  blade.half_x = 0.5 * patch.size_x, blade.half_y = 0.5 * patch.size_y;
  VSURG_TRY(pattern_r, r.Object("pattern"));
  if (Status st = ParseCutPattern(pattern_r, pattern); !st.ok()) return st;
  if (Status st = haptics::CheckBlade(blade); !st.ok()) return st;
  return CheckPatternFits(patch, pattern);
}

}  // namespace scene_detail

Status ParseCut(const json& root, Scene& s) {
  const bool membrane = s.mesh.kind == MeshKind::kMembrane;
  const bool model = s.region.kind == ModelKind::kCutMembrane;
  if (!root.contains("cut")) {
    if (membrane) return InvalidArgument("cut", "cut: a membrane mesh needs the scene's cut");
    if (model)
      return InvalidArgument("regions[0].model.type",
                             "regions[0].model.type: the cut-membrane model needs the scene's cut");
    return Status::Ok();
  }
  const Reader top(root, "");
  VSURG_TRY(c, top.Object("cut"));
  if (!membrane) return InvalidArgument("mesh.type", "mesh.type: a cut scene's mesh is membrane");
  if (!model)
    return InvalidArgument("regions[0].model.type",
                           "regions[0].model.type: a cut scene's model is cut-membrane");
  Scene::CutSpec cut;
  if (Status st = scene_detail::ParseCutParts(c, s.mesh.membrane, cut.blade, cut.pattern); !st.ok())
    return st;
  if (c.Has("grasper")) {
    VSURG_TRY(g, c.Object("grasper"));
    VSURG_TRY(stiffness, g.NumberOr("jaw_stiffness", 2000, 100, 20000));
    VSURG_TRY(reach, g.NumberOr("reach_mm", 4, 0.5, 20));
    cut.grasper = Scene::CutSpec::Grasper{stiffness, reach * 1e-3};
  }
  s.cut = cut;
  // The lattice's nodes (rows of equilateral triangles across the frame) and their copies.
  const tissue::CutMembraneParams& m = s.mesh.membrane;
  const double rows = std::ceil(m.size_y / (m.size_x / m.cells * std::sqrt(3.0) / 2));
  const double nodes = (m.cells + 2.0) * (rows + 1);
  return CheckSessionMemory(ModelKind::kCutMembrane, static_cast<size_t>(2 * nodes),
                            "cut.tissue.cells");
}

Expected<geometry::TriMesh> MembraneSurface(const tissue::CutMembraneParams& params) {
  auto patch = tissue::CutMembrane::Create(params);
  if (!patch.ok()) return patch.error();
  geometry::TriMesh mesh;
  mesh.positions.assign(patch->positions().begin(), patch->positions().end());
  mesh.positions.resize(static_cast<size_t>(patch->ParticleRoom()), geometry::Vec3::Zero());
  mesh.triangles.reserve(static_cast<size_t>(patch->FaceCount()));
  for (int f = 0; f < patch->FaceCount(); ++f) {
    const auto v = patch->face(f).v;
    mesh.triangles.push_back({v[0], v[1], v[2]});
  }
  return mesh;
}

}  // namespace vsurg::sim
