// A scene's tissue law (scene.h, Scene::law): "tissue": { "law": "linear" | "neo-hookean" |
// "exponential", "stiffening": b }. A law other than linear is carried only by a reduced twist
// region (its hyperelastic load levels, tissue/twist_table.h); elsewhere it is refused by name
// rather than silently modelled as linear.
#include <cmath>

#include "common/sim/scene.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

Status ParseLaw(const json& root, Scene& s) {
  if (!root.contains("tissue") || !root["tissue"].is_object()) return Status::Ok();
  const Reader t(root["tissue"], "tissue");
  if (!t.Has("law")) {
    if (t.Has("stiffening")) return t.Bad("stiffening", "is the exponential law's (tissue.law)");
    return Status::Ok();
  }
  VSURG_TRY(law, t.String("law"));
  if (law == "linear") {
    s.law = Scene::Law::kLinear;
  } else if (law == "neo-hookean") {
    s.law = Scene::Law::kNeoHookean;
  } else if (law == "exponential") {
    s.law = Scene::Law::kExponential;
  } else {
    return t.Bad("law", "must be \"linear\", \"neo-hookean\" or \"exponential\"");
  }
  if (s.law == Scene::Law::kExponential) {
    if (!t.Has("stiffening")) return t.Missing("stiffening");
    VSURG_TRY(b, t.Number("stiffening", 1e-6, 100.0));
    s.stiffening = b;
  } else if (t.Has("stiffening")) {
    return t.Bad("stiffening", "is the exponential law's, not \"" + law + "\"'s");
  }
  const bool twist =
      s.region.kind == ModelKind::kReduced && s.region.reduced.mode == ReducedMode::kTwist;
  if (s.law != Scene::Law::kLinear && !twist)
    return t.Bad("law", "\"" + law + "\" is carried only by a reduced twist region");
  return Status::Ok();
}

}  // namespace vsurg::sim
