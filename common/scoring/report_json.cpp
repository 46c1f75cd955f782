#include "common/scoring/report_json.h"

#include <cmath>

#include <nlohmann/json.hpp>

namespace vsurg::scoring {
namespace {

using json = nlohmann::json;

json Number(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}

json Array9(const std::array<double, kIndexCount>& a) {
  json out = json::array();
  for (double v : a) out.push_back(Number(v));
  return out;
}

}  // namespace

json WeightSetToJson(const WeightSet& w) {
  json group = json::object();
  for (int g = 0; g < kGroupCount; ++g)
    group[GroupName(static_cast<EvaluatorGroup>(g))] = w.group[g];
  return {{"name", w.name}, {"group", group}, {"index", Array9(w.index)}};
}

Expected<WeightSet> WeightSetFromJson(const json& j) {
  if (!j.is_object()) return InvalidArgument("weights", "must be a JSON object");
  WeightSet w;
  if (!j.contains("name") || !j["name"].is_string())
    return InvalidArgument("weights.name", "a string is required");
  w.name = j["name"].get<std::string>();
  if (!j.contains("group") || !j["group"].is_object())
    return InvalidArgument("weights.group", "an object {intern, associate_chief, chief}");
  for (auto it = j["group"].begin(); it != j["group"].end(); ++it)
    if (!ParseGroup(it.key()))
      return InvalidArgument("weights.group." + it.key(), "unknown evaluator group");
  for (int g = 0; g < kGroupCount; ++g) {
    const char* name = GroupName(static_cast<EvaluatorGroup>(g));
    if (!j["group"].contains(name) || !j["group"][name].is_number())
      return InvalidArgument(std::string("weights.group.") + name, "a number is required");
    w.group[g] = j["group"][name].get<double>();
  }
  if (!j.contains("index") || !j["index"].is_array() || j["index"].size() != kIndexCount)
    return InvalidArgument("weights.index", "an array of 9 numbers is required");
  for (int i = 0; i < kIndexCount; ++i) {
    if (!j["index"][i].is_number())
      return InvalidArgument("weights.index[" + std::to_string(i) + "]", "must be a number");
    w.index[i] = j["index"][i].get<double>();
  }
  if (Status s = ValidateWeights(w); !s.ok()) {
    Error e = s.error();
    e.field = "weights." + e.field;
    return e;
  }
  return w;
}

Expected<WeightSet> WeightSetFromJsonText(const std::string& text) {
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded())
    return Error{ErrorCode::kParseError, "weight set is not valid JSON", "weights"};
  return WeightSetFromJson(j);
}

json ReportToJson(const EvaluationReport& r) {
  json per_group = json::object(), used = json::object();
  for (int g = 0; g < kGroupCount; ++g) {
    const char* name = GroupName(static_cast<EvaluatorGroup>(g));
    per_group[name] = r.raters_per_group[g];
    used[name] = r.group_weights_used[g];
  }
  json names = json::array();
  for (int j = 0; j < kIndexCount; ++j) names.push_back(IndexName(j));
  return {{"raters", r.raters},
          {"raters_per_group", per_group},
          {"group_weights_used", used},
          {"renormalised", r.renormalised},
          {"absent_groups", r.absent_groups},
          {"index_names", names},
          {"index_means", Array9(r.index_means)},
          {"index_variances", Array9(r.index_variances)},
          {"comprehensive", Number(r.comprehensive)},
          {"icc2k", Number(r.icc2k_indexes)},
          {"icc2k_targets", "indexes"},
          {"cronbach_alpha", Number(r.cronbach_alpha)},
          {"weights", WeightSetToJson(r.weights)}};
}

json ComparisonToJson(const ComparisonReport& r, const std::vector<std::string>& subject_names) {
  json subjects = json::array();
  for (size_t s = 0; s < r.subjects.size(); ++s) {
    json one = ReportToJson(r.subjects[s]);
    one["subject"] = s < subject_names.size() ? subject_names[s] : "";
    subjects.push_back(std::move(one));
  }
  return {{"subjects", subjects},
          {"common_raters", r.common_raters},
          {"icc2k_per_index", Array9(r.icc2k_per_index)}};
}

json TrainingToJson(const std::vector<TrainingCell>& cells) {
  json out = json::array();
  for (const TrainingCell& c : cells)
    out.push_back({{"trainee_group", c.trainee_group},
                   {"moment_min", c.moment_min},
                   {"trainees", c.trainees},
                   {"mean", Number(c.mean)},
                   {"variance", Number(c.variance)}});
  return out;
}

nlohmann::json TrialMetricsToJson(const TrialMetrics& m) {
  return {{"completed", m.completed},
          {"completion_time", m.completion_time},
          {"task_error", m.task_error},
          {"peak_force", m.peak_force},
          {"time_over_force_limit", m.time_over_force_limit},
          {"path_length", m.path_length},
          {"rms_jerk", m.rms_jerk},
          {"overload_events", m.overload_events},
          {"duration", m.duration},
          {"score", m.score},
          {"raw_score", m.raw_score},
          {"capped_not_completed", (m.caps & kCapNotCompleted) != 0},
          {"capped_force_limit", (m.caps & kCapForceLimit) != 0},
          {"capped_overload", (m.caps & kCapOverload) != 0},
          {"capped_back_wall", (m.caps & kCapBackWall) != 0},
          {"guided_share", m.guided_share},
          {"guided_alpha", m.guided_alpha},
          {"lumps", m.lumps},
          {"lumps_found", m.lumps_found},
          {"false_marks", m.false_marks},
          {"localisation_error", m.localisation_error},
          {"coverage", m.coverage},
          {"mean_force", m.mean_force},
          {"depth_error", m.depth_error},
          {"path_deviation", m.path_deviation},
          {"punctures", m.punctures},
          {"extra_punctures", m.extra_punctures},
          {"back_wall_breaches", m.back_wall_breaches},
          {"lateral_strain", m.lateral_strain},
          {"cut_deviation_max", m.cut_deviation_max},
          {"cut_outside", m.cut_outside},
          {"torn_length", m.torn_length},
          {"cut_lifts", m.cut_lifts},
          {"link",
           {{"station_peak_force_n", m.link.station_peak_force},
            {"station_time_over_limit_s", m.link.station_time_over_limit},
            {"rtt_ms", m.link.rtt_ms},
            {"jitter_ms", m.link.jitter_ms},
            {"loss_ratio", m.link.loss},
            {"rate_hz", m.link.rate_hz}}}};
}

}  // namespace vsurg::scoring
