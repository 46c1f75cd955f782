// A scene's tissue law (scene.h, Scene::law): "tissue": { "law": "linear" | "neo-hookean" |
// "exponential", "stiffening": b, "relaxation": [{"g": 0.3, "tau_s": 0.5}, ...] }. A law other than
// linear is carried only by a reduced twist region (its hyperelastic load levels,
// tissue/twist_table.h); elsewhere it is refused by name rather than silently modelled as linear.
#include <cmath>

#include "common/sim/scene.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

namespace {

bool TwistRegion(const Scene& s) {
  return s.region.kind == ModelKind::kReduced && s.region.reduced.mode == ReducedMode::kTwist;
}

// "relaxation": [{"g": share in [0, 1), "tau_s": s > 0}, ...], at most 8 terms, Σ g < 1.
Status ParseRelaxation(const Reader& t, Scene& s) {
  if (!t.Has("relaxation")) return Status::Ok();
  const json& list = t.raw()["relaxation"];
  if (!list.is_array() || list.empty() || list.size() > 8)
    return t.Bad("relaxation", "must be an array of 1 to 8 Prony terms");
  if (!TwistRegion(s)) return t.Bad("relaxation", "is carried only by a reduced twist region");
  double sum = 0;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = "tissue.relaxation[" + std::to_string(i) + "]";
    if (!list[i].is_object()) return InvalidArgument(path, path + ": must be an object");
    const Reader term(list[i], path);
    VSURG_TRY(g, term.Number("g", 0.0, 0.999));
    VSURG_TRY(tau, term.Number("tau_s", 1e-4, 1e4));
    s.relaxation.push_back({g, tau});
    sum += g;
  }
  if (!(sum < 1)) return t.Bad("relaxation", "the terms' g sum to 1 or more (none would remain)");
  return Status::Ok();
}

}  // namespace

Status ParseLaw(const json& root, Scene& s) {
  if (!root.contains("tissue") || !root["tissue"].is_object()) return Status::Ok();
  const Reader t(root["tissue"], "tissue");
  if (Status st = ParseRelaxation(t, s); !st.ok()) return st;
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
  if (s.law != Scene::Law::kLinear && !TwistRegion(s))
    return t.Bad("law", "\"" + law + "\" is carried only by a reduced twist region");
  return Status::Ok();
}

}  // namespace vsurg::sim
