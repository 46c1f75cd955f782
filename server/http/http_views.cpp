#include "server/http/http_views.h"

#include <cmath>

#include "common/core/time.h"
#include "common/scoring/report_json.h"
#include "common/scoring/vocabulary.h"
#include "db/vocabulary.h"

namespace vsurg::server::http {

std::string Iso(int64_t us) {
  return us > 0 ? IsoTimeUtc(us) : std::string();
}

json RecordJson(const db::SessionRecord& r) {
  return {{"id", r.id},
          {"trainee", r.trainee},
          {"scene", r.scene},
          {"state", SessionStateName(r.state)},
          {"created", Iso(r.created_us)},
          {"started", Iso(r.started_us)},
          {"ended", Iso(r.ended_us)},
          {"end_reason", r.end_reason}};
}

json ViewJson(const SessionView& v) {
  json j = RecordJson(v.record);
  j["metrics"] = v.metrics ? scoring::TrialMetricsToJson(*v.metrics) : json(nullptr);
  return j;
}

json UserJson(const db::UserRecord& u) {
  return {{"name", u.name},
          {"role", db::RoleName(u.role)},
          {"group", u.group},
          {"created", Iso(u.created_us)},
          {"disabled", u.disabled}};
}

double Finite(double x) {
  return std::isfinite(x) ? x : 0.0;
}

json Millimetres(const std::vector<geometry::Vec3>& positions) {
  json out = json::array();
  for (const geometry::Vec3& p : positions)
    for (int k = 0; k < 3; ++k) out.push_back(std::round(Finite(p[k]) * 1e5) / 100.0);
  return out;
}

json FiniteOrNull(double x) {
  return std::isfinite(x) ? json(x) : json(nullptr);
}

json TaskJson(const scoring::TaskSpec& t) {
  const scoring::TaskDisplayUnit unit = scoring::DisplayUnitOf(t.kind);
  return {{"kind", scoring::TaskKindName(t.kind)},
          {"target", t.target * unit.per_si},
          {"tolerance", t.tolerance * unit.per_si},
          {"unit", unit.name},
          {"hold_s", t.hold_s},
          {"force_limit_n", t.force_limit},
          {"time_limit_s", t.time_limit}};
}

json ExerciseJson(const ExerciseView& e) {
  json targets = json::array();
  for (const ResolvedTarget& t : e.targets) {
    const scoring::MetricDef* def = scoring::FindMetric(t.metric);
    targets.push_back(
        {{"metric", t.metric},
         {"unit", def ? def->unit : ""},
         {"better", def && def->better == scoring::Better::kHigher ? "higher" : "lower"},
         {"value", t.value ? json(*t.value) : json(nullptr)},
         {"from_experts", t.from_experts},
         {"expert_trials", t.expert_trials}});
  }
  return {{"id", e.record.id},
          {"position", e.record.position},
          {"title", e.record.title},
          {"scene", e.record.scene},
          {"spec", json::parse(e.record.spec_json, nullptr, false)},
          {"targets", targets},
          {"ready", e.ready},
          {"task", e.task ? TaskJson(*e.task) : json(nullptr)}};
}

json CourseJson(const CourseView& c) {
  json exercises = json::array();
  for (const ExerciseView& e : c.exercises) exercises.push_back(ExerciseJson(e));
  return {{"id", c.record.id},
          {"name", c.record.name},
          {"description", c.record.description},
          {"owner", c.record.owner},
          {"created", Iso(c.record.created_us)},
          {"exercises", exercises}};
}

json ChecksJson(const scoring::AttemptCheck& a) {
  json out = json::array();
  for (const scoring::TargetCheck& t : a.checks)
    out.push_back({{"metric", std::string(t.metric)},
                   {"value", FiniteOrNull(t.value)},
                   {"target", t.target},
                   {"met", t.met}});
  return out;
}

json ProgressJson(const ExerciseProgress& ep) {
  const scoring::Progress& p = ep.progress;
  return {{"exercise_id", ep.exercise_id},
          {"state", CellStateName(ep.state)},
          {"attempts", p.attempts},
          {"passes", p.passes},
          {"streak", p.streak},
          {"proficient_at", p.proficient_at ? json(*p.proficient_at) : json(nullptr)},
          {"proficient", Iso(ep.proficient_us)},
          {"last", Iso(ep.last_us)},
          {"attempts_today", p.attempts_today},
          {"may_attempt", p.may_attempt},
          {"to_improve", ep.to_improve},
          {"last_checks", p.checks.empty() ? json::array() : ChecksJson(p.checks.back())}};
}

json TraineeProgressJson(const TraineeProgress& t, bool compact) {
  json cells = json::array();
  for (const ExerciseProgress& ep : t.exercises) {
    if (!compact) {
      cells.push_back(ProgressJson(ep));
      continue;
    }
    const scoring::Progress& p = ep.progress;
    cells.push_back({{"exercise_id", ep.exercise_id},
                     {"state", CellStateName(ep.state)},
                     {"attempts", p.attempts},
                     {"passes", p.passes},
                     {"streak", p.streak},
                     {"proficient_at", p.proficient_at ? json(*p.proficient_at) : json(nullptr)}});
  }
  return {{"trainee", t.trainee},
          {"stalled", t.stalled},
          {"completed", t.completed},
          {"next_exercise", t.next_exercise ? json(*t.next_exercise) : json(nullptr)},
          {"exercises", cells}};
}

json MetricsJson(const scoring::TrialMetrics& m) {
  json out = json::object();
  for (const scoring::MetricDef& def : scoring::ProficiencyMetrics())
    out[std::string(def.name)] = FiniteOrNull(scoring::MetricValue(m, def));
  return out;
}

}  // namespace vsurg::server::http
