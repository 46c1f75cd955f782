// An exercise's spec: its JSON (the targets, the proficiency rule, the benchmark, the CUSUM, the
// task's settings) parsed and checked field by field, and written back.
#include <algorithm>
#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "server/domain/scene_catalog.h"
#include "server/domain/training.h"

namespace vsurg::server {
namespace {

using nlohmann::json;
using scoring::ProficiencyMetrics;

// A number field: none when absent or null, NaN when not a number (refused by its range check).
std::optional<double> Number(const json& j, const char* name) {
  const auto it = j.find(name);
  if (it == j.end() || it->is_null()) return std::nullopt;
  if (!it->is_number()) return std::nan("");
  return it->get<double>();
}

}  // namespace

Expected<ExerciseSpec> ParseExerciseSpec(std::string_view text) {
  json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    return Error{ErrorCode::kParseError, "an exercise's spec is a JSON object", "spec"};
  ExerciseSpec s;
  const auto targets = j.find("targets");
  if (targets == j.end() || !targets->is_array() || targets->empty() || targets->size() > 16)
    return InvalidArgument("targets",
                           "1 to 16 targets, each {metric, value} or "
                           "{metric, from_experts: true}");
  for (size_t i = 0; i < targets->size(); ++i) {
    const json& t = (*targets)[i];
    const std::string field = "targets[" + std::to_string(i) + "]";
    if (!t.is_object() || !t.contains("metric") || !t["metric"].is_string())
      return InvalidArgument(field, "needs a metric name");
    TargetSpec ts{t["metric"].get<std::string>(), Number(t, "value")};
    if (!scoring::FindMetric(ts.metric)) {
      std::string names;
      for (const scoring::MetricDef& m : ProficiencyMetrics())
        names += (names.empty() ? "" : ", ") + std::string(m.name);
      return InvalidArgument(field, "unknown metric '" + ts.metric + "' (one of " + names + ")");
    }
    const bool experts = t.value("from_experts", false);
    if (experts == ts.value.has_value())
      return InvalidArgument(field, "give a value or from_experts: true (one of the two)");
    if (ts.value && !std::isfinite(*ts.value)) return InvalidArgument(field, "a finite value");
    for (const TargetSpec& other : s.targets)
      if (other.metric == ts.metric) return InvalidArgument(field, "a metric appears once");
    s.targets.push_back(std::move(ts));
  }
  const auto consecutive = Number(j, "consecutive").value_or(2);
  if (!(consecutive >= 1 && consecutive <= 20) || consecutive != std::floor(consecutive))
    return InvalidArgument("consecutive", "passes in a row: 1 to 20");
  s.rule.consecutive = static_cast<int>(consecutive);
  const auto per_day = Number(j, "max_attempts_per_day").value_or(0);
  if (!(per_day >= 0 && per_day <= 1000) || per_day != std::floor(per_day))
    return InvalidArgument("max_attempts_per_day", "0 (no limit) to 1000");
  s.rule.max_attempts_per_day = static_cast<int>(per_day);
  if (j.contains("unlock_in_order")) {
    if (!j["unlock_in_order"].is_boolean()) return InvalidArgument("unlock_in_order", "a boolean");
    s.unlock_in_order = j["unlock_in_order"].get<bool>();
  }
  if (j.contains("benchmark") && !j["benchmark"].is_string())
    return InvalidArgument("benchmark", "mean_sd or best_quartile, as text");
  const std::string bench = j.contains("benchmark") ? j["benchmark"].get<std::string>() : "mean_sd";
  if (bench == "mean_sd")
    s.benchmark = scoring::BenchmarkMode::kMeanSd;
  else if (bench == "best_quartile")
    s.benchmark = scoring::BenchmarkMode::kBestQuartile;
  else
    return InvalidArgument("benchmark", "mean_sd or best_quartile");
  s.k = Number(j, "k").value_or(1.0);
  if (!(s.k >= 0 && s.k <= 5)) return InvalidArgument("k", "0 to 5 standard deviations");
  if (const auto c = j.find("cusum"); c != j.end() && !c->is_null()) {
    if (!c->is_object()) return InvalidArgument("cusum", "an object {p0, p1, alpha, beta}");
    s.cusum.p0 = Number(*c, "p0").value_or(s.cusum.p0);
    s.cusum.p1 = Number(*c, "p1").value_or(s.cusum.p1);
    s.cusum.alpha = Number(*c, "alpha").value_or(s.cusum.alpha);
    s.cusum.beta = Number(*c, "beta").value_or(s.cusum.beta);
    if (auto l = scoring::CusumLimitsOf(s.cusum); !l.ok())
      return InvalidArgument("cusum." + l.error().field, l.error().message);
  }
  const auto stall = Number(j, "stall_after").value_or(5);
  if (!(stall >= 1 && stall <= 100) || stall != std::floor(stall))
    return InvalidArgument("stall_after", "1 to 100 failed attempts in a row");
  s.stall_after = static_cast<int>(stall);
  if (const auto t = j.find("task"); t != j.end() && !t->is_null()) {
    if (!t->is_object()) return InvalidArgument("task", "an object of the task's settings");
    constexpr double kDeg = 3.14159265358979323846 / 180.0;
    for (const auto& [key, value] : t->items()) {
      static constexpr std::array<std::string_view, 7> kKeys = {
          "target_deg", "tolerance_deg", "target_depth_m", "tolerance_m",
          "hold_s",     "force_limit_n", "time_limit_s"};
      if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end())
        return InvalidArgument("task." + key,
                               "not a task setting (target_deg, tolerance_deg, target_depth_m, "
                               "tolerance_m, hold_s, force_limit_n, time_limit_s)");
      if (!value.is_number() || !std::isfinite(value.get<double>()))
        return InvalidArgument("task." + key, "a finite number");
    }
    scoring::TaskSettings& ts = s.task;
    const bool degrees = t->contains("target_deg") || t->contains("tolerance_deg");
    const bool metres = t->contains("target_depth_m") || t->contains("tolerance_m");
    if (degrees && metres)
      return InvalidArgument("task",
                             "a twist's target (target_deg) or a press's "
                             "(target_depth_m), not both");
    if (degrees) ts.kind = scoring::TaskKind::kTwist;
    if (metres) ts.kind = scoring::TaskKind::kPress;
    const double unit = degrees ? kDeg : 1.0;
    if (auto v = Number(*t, degrees ? "target_deg" : "target_depth_m")) ts.target = *v * unit;
    if (auto v = Number(*t, degrees ? "tolerance_deg" : "tolerance_m")) ts.tolerance = *v * unit;
    ts.hold_s = Number(*t, "hold_s");
    ts.force_limit = Number(*t, "force_limit_n");
    ts.time_limit = Number(*t, "time_limit_s");
  }
  return s;
}

namespace {
json TaskSettingsJson(const scoring::TaskSettings& t) {
  json o = json::object();
  const bool twist = t.kind.value_or(scoring::TaskKind::kTwist) == scoring::TaskKind::kTwist;
  const double unit = twist ? 180.0 / 3.14159265358979323846 : 1.0;
  if (t.target) o[twist ? "target_deg" : "target_depth_m"] = *t.target * unit;
  if (t.tolerance) o[twist ? "tolerance_deg" : "tolerance_m"] = *t.tolerance * unit;
  if (t.hold_s) o["hold_s"] = *t.hold_s;
  if (t.force_limit) o["force_limit_n"] = *t.force_limit;
  if (t.time_limit) o["time_limit_s"] = *t.time_limit;
  return o;
}

}  // namespace

// The exercise's task settings must fit its scene's task (a twist's target on a twist scene, a
// time limit longer than the hold, …); `field` names the exercise in the error.
Status CheckTaskFits(const std::vector<SceneInfo>& scenes, const std::string& scene,
                     const ExerciseSpec& spec, const std::string& field) {
  const auto it = std::find_if(scenes.begin(), scenes.end(),
                               [&](const SceneInfo& s) { return s.name == scene; });
  if (it == scenes.end())
    return InvalidArgument(field + ".scene", "no usable scene '" + scene + "'");
  if (spec.task.empty()) return Status::Ok();
  auto applied = scoring::ApplyTaskSettings(it->spec, spec.task);
  if (!applied.ok())
    return InvalidArgument(field + ".spec.task." + applied.error().field, applied.error().message);
  return Status::Ok();
}

std::string ExerciseSpecJson(const ExerciseSpec& s) {
  json targets = json::array();
  for (const TargetSpec& t : s.targets) {
    json o = {{"metric", t.metric}};
    if (t.value)
      o["value"] = *t.value;
    else
      o["from_experts"] = true;
    targets.push_back(std::move(o));
  }
  return json{
      {"targets", targets},
      {"consecutive", s.rule.consecutive},
      {"max_attempts_per_day", s.rule.max_attempts_per_day},
      {"unlock_in_order", s.unlock_in_order},
      {"benchmark", s.benchmark == scoring::BenchmarkMode::kMeanSd ? "mean_sd" : "best_quartile"},
      {"k", s.k},
      {"cusum",
       {{"p0", s.cusum.p0}, {"p1", s.cusum.p1}, {"alpha", s.cusum.alpha}, {"beta", s.cusum.beta}}},
      {"stall_after", s.stall_after},
      {"task", TaskSettingsJson(s.task)}}
      .dump();
}

}  // namespace vsurg::server
