// A scene's needle tissue (scene.h, haptics/needle.h): its layers from the skin down and its
// target, in a scene file's units (mm, N, N/m), into the model's (m).
//
//   "needle": {
//     "layers": [ { "name": "skin", "thickness_mm": 2,
//                   "a1": 100, "a2": 20000, "puncture_n": 1.5,         (its top's law)
//                   "friction_static": 30, "friction_sliding": 20,      (N per m of shaft)
//                   "friction_viscous": 100, "cutting_n": 0.8,
//                   "lateral_stiffness": 2000 }, … ],
//     "target": { "type": "vessel" | "cyst", "name": "vein", "depth_mm": 20,
//                 "offset_mm": [x, y], "axis": [x, y, z], "radius_mm": 4,
//                 "wall": { "a1": 200, "a2": 0, "puncture_n": 0.6 } },
//     "velocity_deadzone": 0.002, "stick_stiffness": 300, "max_entry_angle_deg": 75 }
//
// The skin is the top of the scene's block (mesh type "block"): z = its height, over its
// rectangle. Each value is checked by the model's own rules (haptics::CheckNeedleTissue), by
// the scene file's path.
#include <numbers>

#include "common/sim/scene.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

namespace {

Expected<haptics::PunctureLaw> ParseLaw(const Reader& r) {
  haptics::PunctureLaw law;
  VSURG_TRY(a1, r.NumberOr("a1", 0, 0, 1e5));
  VSURG_TRY(a2, r.NumberOr("a2", 0, 0, 1e8));
  VSURG_TRY(puncture, r.Number("puncture_n", 1e-3, 50));
  law.a1 = a1, law.a2 = a2, law.puncture = puncture;
  if (!(a1 > 0 || a2 > 0)) return r.Bad("a1", "a boundary needs a stiffness (a1 or a2 > 0)");
  return law;
}

Expected<haptics::NeedleLayer> ParseLayer(const Reader& r) {
  haptics::NeedleLayer l;
  VSURG_TRY(name, r.StringOr("name", "layer"));
  VSURG_TRY(thickness, r.Number("thickness_mm", 0.1, 500));
  VSURG_TRY(law, ParseLaw(r));
  VSURG_TRY(fs, r.NumberOr("friction_static", 0, 0, 1e5));
  VSURG_TRY(fc, r.NumberOr("friction_sliding", 0, 0, 1e5));
  VSURG_TRY(fv, r.NumberOr("friction_viscous", 0, 0, 1e6));
  VSURG_TRY(cutting, r.NumberOr("cutting_n", 0, 0, 50));
  VSURG_TRY(lateral, r.NumberOr("lateral_stiffness", 0, 0, 1e6));
  if (fc > fs)
    return r.Bad("friction_sliding",
                 "must not exceed friction_static (Karnopp: the static "
                 "limit is the larger)");
  l.name = name;
  l.thickness = thickness * 1e-3;
  l.top = law;
  l.friction_static = fs, l.friction_sliding = fc, l.friction_viscous = fv;
  l.cutting = cutting;
  l.lateral_stiffness = lateral;
  return l;
}

Status ParseTarget(const Reader& n, haptics::NeedleTissueSpec& spec) {
  VSURG_TRY(t, n.Object("target"));
  VSURG_TRY(type, t.String("type"));
  haptics::NeedleTarget& target = spec.target;
  if (type == "vessel") {
    target.kind = haptics::NeedleTarget::Kind::kVessel;
  } else if (type == "cyst") {
    target.kind = haptics::NeedleTarget::Kind::kCyst;
  } else {
    return t.Bad("type", "must be vessel or cyst, got '" + type + "'");
  }
  VSURG_TRY(name, t.StringOr("name", type));
  VSURG_TRY(depth, t.Number("depth_mm", 1, 500));
  VSURG_TRY(radius, t.Number("radius_mm", 0.5, 50));
  VSURG_TRY(offset, t.NumbersOr("offset_mm", 2, -1000, 1000));
  VSURG_TRY(axis, t.NumbersOr("axis", 3, -1, 1));
  VSURG_TRY(wall_reader, t.Object("wall"));
  VSURG_TRY(wall, ParseLaw(wall_reader));
  target.name = name;
  target.radius = radius * 1e-3;
  target.centre = {spec.centre_x + (offset.empty() ? 0.0 : offset[0] * 1e-3),
                   spec.centre_y + (offset.empty() ? 0.0 : offset[1] * 1e-3),
                   spec.surface_z - depth * 1e-3};
  if (!axis.empty()) target.axis = {axis[0], axis[1], axis[2]};
  if (!(target.axis.norm() > 0.5)) return t.Bad("axis", "must be a direction");
  target.wall = wall;
  if (depth <= radius) return t.Bad("depth_mm", "the target must lie wholly under the skin");
  spec.has_target = true;
  return Status::Ok();
}

}  // namespace

Status ParseNeedle(const json& root, Scene& s) {
  if (!root.contains("needle")) return Status::Ok();
  const Reader top(root, "");
  VSURG_TRY(n, top.Object("needle"));
  if (s.mesh.kind != MeshKind::kBlock)
    return n.Bad("layers", "a needle's layers lie under a block's top: the mesh must be a block");
  haptics::NeedleTissueSpec spec;
  spec.surface_z = s.mesh.block.size.z();
  spec.half_x = 0.5 * s.mesh.block.size.x();
  spec.half_y = 0.5 * s.mesh.block.size.y();
  const json& layers = n.raw().contains("layers") ? n.raw()["layers"] : json();
  if (!layers.is_array() || layers.empty() || layers.size() > haptics::kMaxNeedleLayers)
    return n.Bad("layers", "must list 1 to " + std::to_string(haptics::kMaxNeedleLayers) +
                               " layers, from the skin down");
  for (size_t i = 0; i < layers.size(); ++i) {
    const std::string path = "needle.layers[" + std::to_string(i) + "]";
    if (!layers[i].is_object()) return InvalidArgument(path, path + ": must be an object");
    VSURG_TRY(layer, ParseLayer(Reader(layers[i], path)));
    spec.layers.push_back(layer);
  }
  if (n.Has("target"))
    if (Status st = ParseTarget(n, spec); !st.ok()) return st;
  VSURG_TRY(deadzone, n.NumberOr("velocity_deadzone", spec.velocity_deadzone, 1e-5, 0.1));
  VSURG_TRY(stick, n.NumberOr("stick_stiffness", spec.stick_stiffness, 1, 1e4));
  VSURG_TRY(angle, n.NumberOr("max_entry_angle_deg", 75, 1, 89));
  spec.velocity_deadzone = deadzone;
  spec.stick_stiffness = stick;
  spec.max_entry_angle = angle * std::numbers::pi / 180;
  if (Status st = haptics::CheckNeedleTissue(spec); !st.ok()) return st;
  s.needle = std::move(spec);
  return Status::Ok();
}

}  // namespace vsurg::sim
