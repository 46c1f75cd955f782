// The pattern-cutting drill (cut_drill.h): the drill file, the scripted hand, and the loop.
#include "common/sim/cut_drill.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/core/file.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

namespace {

constexpr double kDeg = std::numbers::pi / 180;

Status ParseTissue(const Reader& r, tissue::CutMembraneParams& p) {
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

Status ParseBlade(const Reader& r, haptics::BladeParams& b) {
  VSURG_TRY(toughness, r.Number("toughness", 1, 1e6));
  VSURG_TRY(angle, r.NumberOr("angle_deg", 0, 0, 79));
  VSURG_TRY(width, r.Number("width_mm", 0.01, 5));
  b.toughness = toughness, b.angle = angle * kDeg, b.width = width * 1e-3;
  return Status::Ok();
}

Status ParsePattern(const Reader& r, scoring::CutPattern& p) {
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
Status CheckFits(const CutDrillSpec& s) {
  const scoring::CutPattern& p = s.task.pattern;
  const double margin = p.band + 2 * s.tissue.size_x / s.tissue.cells;
  const double hx = 0.5 * s.tissue.size_x - margin, hy = 0.5 * s.tissue.size_y - margin;
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

Expected<CutDrillSpec> ParseCutDrill(const std::string& json_text, const std::string& source) {
  json root = json::parse(json_text, nullptr, false);
  if (root.is_discarded() || !root.is_object())
    return Error{ErrorCode::kParseError, source + ": not a JSON object", "file"};
  const Reader top(root, "");
  CutDrillSpec s;
  s.source = source;
  VSURG_TRY(name, top.String("name"));
  VSURG_TRY(description, top.StringOr("description", ""));
  s.name = name, s.description = description;
  VSURG_TRY(tissue_r, top.Object("tissue"));
  if (Status st = ParseTissue(tissue_r, s.tissue); !st.ok()) return st.error();
  VSURG_TRY(blade_r, top.Object("blade"));
  if (Status st = ParseBlade(blade_r, s.blade); !st.ok()) return st.error();
  s.blade.thickness = s.tissue.thickness;
  s.blade.half_x = 0.5 * s.tissue.size_x, s.blade.half_y = 0.5 * s.tissue.size_y;
  VSURG_TRY(pattern_r, top.Object("pattern"));
  if (Status st = ParsePattern(pattern_r, s.task.pattern); !st.ok()) return st.error();
  VSURG_TRY(task_r, top.Object("task"));
  VSURG_TRY(limit, task_r.NumberOr("force_limit_n", 3, 0.1, 50));
  VSURG_TRY(time, task_r.NumberOr("time_limit_s", 120, 5, 3600));
  VSURG_TRY(expert, task_r.NumberOr("expert_time_s", 25, 1, 3600));
  s.task.force_limit = limit, s.task.time_limit = time, s.task.expert_time = expert;
  if (Status st = haptics::CheckBlade(s.blade); !st.ok()) return st.error();
  if (Status st = CheckFits(s); !st.ok()) return st.error();
  return s;
}

Expected<CutDrillSpec> LoadCutDrill(const std::string& path) {
  auto text = ReadTextFile(path, "drill");
  if (!text.ok()) return text.error();
  return ParseCutDrill(*text, path);
}

CutHand CutHand::Expert(uint32_t seed) {
  return {0.006, 0.0002, 0, seed, 0.003, 0.0};
}
CutHand CutHand::Novice(uint32_t seed) {
  return {0.003, 0.0015, 2, seed, 0.003, 0.004};
}

}  // namespace vsurg::sim
