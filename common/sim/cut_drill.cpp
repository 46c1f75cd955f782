// The pattern-cutting drill (cut_drill.h): the drill file, the scripted hand, and the loop.
#include "common/sim/cut_drill.h"

#include "common/core/file.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {

using scene_detail::json;
using scene_detail::Reader;

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
  if (Status st = scene_detail::ParseCutParts(top, s.tissue, s.blade, s.task.pattern); !st.ok())
    return st.error();
  VSURG_TRY(task_r, top.Object("task"));
  VSURG_TRY(limit, task_r.NumberOr("force_limit_n", 3, 0.1, 50));
  VSURG_TRY(time, task_r.NumberOr("time_limit_s", 120, 5, 3600));
  VSURG_TRY(expert, task_r.NumberOr("expert_time_s", 25, 1, 3600));
  s.task.force_limit = limit, s.task.time_limit = time, s.task.expert_time = expert;
  return s;
}

Expected<haptics::BladeModel> BladeOnPatch(haptics::BladeParams blade,
                                           const tissue::CutMembrane& patch) {
  blade.in_plane_stiffness = patch.InPlaneStiffness();
  blade.normal_stiffness = patch.NormalStiffness();
  return haptics::BladeModel::Create(blade);
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
