// The dashboard's training-programme routes (server/domain/training.h): courses, cohorts, their
// grid a page at a time, curves, enrolments, experts, a trainee's own progress, exports.
#include <nlohmann/json.hpp>

#include "common/core/time.h"
#include "common/scoring/report_json.h"
#include "common/scoring/vocabulary.h"
#include "db/vocabulary.h"
#include "server/domain/scene_catalog.h"
#include "server/domain/training.h"
#include "server/http/http_reply.h"
#include "server/http/http_routes.h"
#include "server/http/http_views.h"
#include "server/ops/metrics.h"

namespace vsurg::server::http {

// --- the training programme ---

namespace {
// A list of names from a JSON body field (an array of strings).
Expected<std::vector<std::string>> Names(const json& body, const char* field) {
  std::vector<std::string> out;
  const auto it = body.find(field);
  if (it == body.end() || it->is_null()) return out;
  if (!it->is_array()) return InvalidArgument(field, "a list of names");
  for (const json& n : *it) {
    if (!n.is_string()) return InvalidArgument(field, "a list of names");
    out.push_back(n.get<std::string>());
  }
  return out;
}
// A spec from a JSON body field, through the one parser.
Expected<ExerciseSpec> SpecOf(const json& j, const std::string& field) {
  auto spec = ParseExerciseSpec(j.dump());
  if (!spec.ok())
    return Error{spec.error().code, spec.error().message, field + "." + spec.error().field};
  return spec;
}
}  // namespace

HttpReply HttpApi::Routes::Courses(const Call& c) {
  auto list = ListCourses(c.api.d_, *c.p);
  if (!list.ok()) return ErrorReply(list.error());
  json out = json::array();
  for (const CourseView& v : *list) out.push_back(CourseJson(v));
  return Ok({{"courses", out}});
}

HttpReply HttpApi::Routes::CourseCreate(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto name = Field<std::string>(*body, "name", "");
  auto description = Field<std::string>(*body, "description", "");
  if (!name.ok()) return ErrorReply(name.error());
  if (!description.ok()) return ErrorReply(description.error());
  const auto list = body->find("exercises");
  if (list == body->end() || !list->is_array())
    return ErrorReply(InvalidArgument("exercises", "a list of {title, scene, spec}"));
  std::vector<NewExercise> exercises;
  for (size_t i = 0; i < list->size(); ++i) {
    const json& e = (*list)[i];
    const std::string field = "exercises[" + std::to_string(i) + "]";
    if (!e.is_object() || !e.value("title", json()).is_string() ||
        !e.value("scene", json()).is_string() || !e.contains("spec"))
      return ErrorReply(InvalidArgument(field, "needs a title, a scene and a spec"));
    auto spec = SpecOf(e["spec"], field + ".spec");
    if (!spec.ok()) return ErrorReply(spec.error());
    exercises.push_back({e["title"].get<std::string>(), e["scene"].get<std::string>(), *spec});
  }
  auto made = CreateCourse(c.api.d_, *c.p, *name, *description, exercises);
  if (!made.ok()) return ErrorReply(made.error());
  return Json(201, {{"course", CourseJson(*made)}});
}

HttpReply HttpApi::Routes::CourseGet(const Call& c) {
  auto v = GetCourse(c.api.d_, *c.p, static_cast<int64_t>(c.id));
  if (!v.ok()) return ErrorReply(v.error());
  return Ok(CourseJson(*v));
}

HttpReply HttpApi::Routes::ExerciseSpecPut(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto spec = SpecOf(*body, "spec");
  if (!spec.ok()) return ErrorReply(spec.error());
  if (Status s = SetExerciseSpec(c.api.d_, *c.p, static_cast<int64_t>(c.id), *spec); !s.ok())
    return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::Cohorts(const Call& c) {
  auto list = ListCohorts(c.api.d_, *c.p);
  if (!list.ok()) return ErrorReply(list.error());
  json out = json::array();
  for (const db::CohortRecord& h : *list)
    out.push_back({{"id", h.id},
                   {"name", h.name},
                   {"instructor", h.instructor},
                   {"created", Iso(h.created_us)},
                   {"members", h.members}});
  return Ok({{"cohorts", out}});
}

HttpReply HttpApi::Routes::CohortCreate(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto name = Field<std::string>(*body, "name", "");
  auto instructor = Field<std::string>(*body, "instructor", "");
  auto members = Names(*body, "members");
  if (!name.ok()) return ErrorReply(name.error());
  if (!instructor.ok()) return ErrorReply(instructor.error());
  if (!members.ok()) return ErrorReply(members.error());
  auto made = CreateCohort(c.api.d_, *c.p, *name, *instructor, *members);
  if (!made.ok()) return ErrorReply(made.error());
  return Json(201,
              {{"cohort", {{"id", made->id}, {"name", made->name}, {"members", made->members}}}});
}

HttpReply HttpApi::Routes::CohortMembers(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto members = Names(*body, "members");
  if (!members.ok()) return ErrorReply(members.error());
  if (Status s = AddCohortMembers(c.api.d_, *c.p, static_cast<int64_t>(c.id), *members); !s.ok())
    return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::CohortGrid(const Call& c) {
  const auto course = QueryNumber(c.query, "course");
  if (!course || *course == 0) return ErrorReply(InvalidArgument("course", "a course id"));
  const auto offset = QueryNumber(c.query, "offset");
  const auto limit = QueryNumber(c.query, "limit");
  if (!offset) return ErrorReply(InvalidArgument("offset", "a number of trainees, 0 or more"));
  if (!limit) return ErrorReply(InvalidArgument("limit", "a number of trainees"));
  const GridPage page{.offset = *offset, .limit = *limit == 0 ? kMaxGridTrainees : *limit};
  return c.api.OffThread(*c.p, [&d = c.api.d_, p = *c.p, cohort = c.id, course = *course, page] {
    auto grid = CohortProgress(d, p, static_cast<int64_t>(cohort), course, page);
    if (!grid.ok()) return ErrorReply(grid.error());
    json trainees = json::array();
    for (const TraineeProgress& t : grid->trainees)
      trainees.push_back(TraineeProgressJson(t, true));
    return Ok({{"course", CourseJson(grid->course)},
               {"cohort", cohort},
               {"trainees", trainees},
               {"offset", grid->offset},
               {"limit", page.limit},
               {"total_trainees", grid->total_trainees}});
  });
}

HttpReply HttpApi::Routes::CohortCurveRoute(const Call& c) {
  const auto exercise = QueryNumber(c.query, "exercise");
  if (!exercise || *exercise == 0) return ErrorReply(InvalidArgument("exercise", "an exercise id"));
  return c.api.OffThread(*c.p, [&d = c.api.d_, p = *c.p, cohort = c.id, exercise = *exercise] {
    return CohortCurveReply(d, p, cohort, exercise);
  });
}

HttpReply HttpApi::Routes::CohortCurveReply(Domain& d, const db::Principal& p, uint64_t cohort,
                                            int64_t exercise) {
  auto curve = CohortCurveOf(d, p, static_cast<int64_t>(cohort), exercise);
  if (!curve.ok()) return ErrorReply(curve.error());
  json metrics = json::array();
  for (const MetricCurve& m : curve->metrics) {
    json points = json::array();
    for (const CurvePoint& pt : m.points)
      points.push_back(
          {{"n", pt.attempt}, {"trainees", pt.trainees}, {"mean", pt.mean}, {"sd", pt.sd}});
    metrics.push_back(
        {{"metric", m.metric},
         {"target", m.target ? json(*m.target) : json(nullptr)},
         {"points", points},
         {"experts", {{"trials", m.expert_trials}, {"mean", m.expert_mean}, {"sd", m.expert_sd}}}});
  }
  return Ok({{"exercise", ExerciseJson(curve->exercise)}, {"metrics", metrics}});
}

HttpReply HttpApi::Routes::EnrolRoute(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto course = Field<int64_t>(*body, "course", 0);
  auto cohort = Field<int64_t>(*body, "cohort", 0);
  auto trainee = Field<std::string>(*body, "trainee", "");
  for (const Error* e : {Err(course), Err(cohort)})
    if (e) return ErrorReply(*e);
  if (!trainee.ok()) return ErrorReply(trainee.error());
  db::EnrolmentRecord e;
  e.course_id = *course;
  if (*cohort != 0) e.cohort_id = *cohort;
  e.trainee = *trainee;
  // Dates as ISO times; "starts" absent: now, "ends" absent: open-ended.
  for (const char* name : {"starts", "ends"}) {
    auto v = Field<std::string>(*body, name, "");
    if (!v.ok()) return ErrorReply(v.error());
    if (v->empty()) continue;
    auto t = ParseIsoUtc(*v, name);
    if (!t.ok()) return ErrorReply(t.error());
    if (std::string_view(name) == "starts")
      e.starts_us = *t;
    else
      e.ends_us = *t;
  }
  auto made = Enrol(c.api.d_, *c.p, e);
  if (!made.ok()) return ErrorReply(made.error());
  return Json(201, {{"enrolment", made->id}});
}

HttpReply HttpApi::Routes::Experts(const Call& c) {
  auto list = ListExperts(c.api.d_, *c.p);
  if (!list.ok()) return ErrorReply(list.error());
  return Ok({{"experts", *list}});
}

HttpReply HttpApi::Routes::ExpertSet(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto trainee = Field<std::string>(*body, "trainee", "");
  auto expert = Field<bool>(*body, "expert", true);
  if (!trainee.ok()) return ErrorReply(trainee.error());
  if (!expert.ok()) return ErrorReply(expert.error());
  if (Status s = SetExpert(c.api.d_, *c.p, *trainee, *expert); !s.ok())
    return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::TrainingMine(const Call& c) {
  std::string trainee = Param(c.query, "trainee");
  if (trainee.empty()) trainee = c.p->name;
  auto courses = TraineeCourses(c.api.d_, *c.p, trainee);
  if (!courses.ok()) return ErrorReply(courses.error());
  json out = json::array();
  for (const CourseProgress& cp : *courses)
    out.push_back({{"course", CourseJson(cp.course)},
                   {"progress", TraineeProgressJson(cp.trainees.front())}});
  return Ok({{"trainee", trainee}, {"courses", out}});
}

HttpReply HttpApi::Routes::TrainingCurve(const Call& c) {
  std::string trainee = Param(c.query, "trainee");
  if (trainee.empty()) trainee = c.p->name;
  const auto exercise = QueryNumber(c.query, "exercise");
  if (!exercise || *exercise == 0) return ErrorReply(InvalidArgument("exercise", "an exercise id"));
  auto curve = TraineeCurve(c.api.d_, *c.p, trainee, *exercise);
  if (!curve.ok()) return ErrorReply(curve.error());
  json attempts = json::array();
  const auto& checks = curve->progress.progress.checks;
  for (size_t i = 0; i < curve->attempts.size() && i < checks.size(); ++i) {
    const db::AttemptRow& a = curve->attempts[i];
    attempts.push_back({{"n", i + 1},
                        {"session", a.session_id},
                        {"at", Iso(a.ended_us)},
                        {"passed", checks[i].passed},
                        {"metrics", MetricsJson(a.metrics)},
                        {"checks", ChecksJson(checks[i])}});
  }
  const scoring::CusumCurve& k = curve->cusum;
  const scoring::CusumParams& cp = curve->exercise.spec.cusum;
  return Ok(
      {{"trainee", trainee},
       {"course", {{"id", curve->course.record.id}, {"name", curve->course.record.name}}},
       {"exercise", ExerciseJson(curve->exercise)},
       {"progress", ProgressJson(curve->progress)},
       {"attempts", attempts},
       {"cusum",
        {{"values", k.values},
         {"s", k.limits.s},
         {"h0", k.limits.h0},
         {"h1", k.limits.h1},
         {"p0", cp.p0},
         {"p1", cp.p1},
         {"alpha", cp.alpha},
         {"beta", cp.beta},
         {"proficient_at", k.proficient_at ? json(*k.proficient_at) : json(nullptr)},
         {"unacceptable_at", k.unacceptable_at ? json(*k.unacceptable_at) : json(nullptr)}}}});
}

HttpReply HttpApi::Routes::TrainingNext(const Call& c) {
  auto next = NextExerciseOf(c.api.d_, *c.p, Param(c.query, "trainee"));
  if (!next.ok()) return ErrorReply(next.error());
  if (!next->course || !next->exercise_id) return Ok({{"next", nullptr}});
  return Ok({{"course", CourseJson(*next->course)},
             {"next", *next->exercise_id},
             {"open", next->open},
             {"progress", ProgressJson(next->progress)}});
}

HttpReply HttpApi::Routes::TrainingExport(const Call& c) {
  const auto course = QueryNumber(c.query, "course");
  const auto cohort = QueryNumber(c.query, "cohort");
  if (!course) return ErrorReply(InvalidArgument("course", "a course id"));
  if (!cohort) return ErrorReply(InvalidArgument("cohort", "a cohort id"));
  const std::string name = Param(c.query, "format");
  const auto format = db::ParseExportFormat(name.empty() ? "csv" : name);
  if (!format) return ErrorReply(InvalidArgument("format", "csv, jsonl or xapi"));
  // Refusals as replies; the progress is then computed and its lines streamed on an export
  // worker (xAPI of a large cohort runs to tens of megabytes).
  if (Status s = MayExportProgress(c.api.d_, *c.p, *course, *cohort); !s.ok())
    return ErrorReply(s.error());
  HttpReply reply;
  reply.kind = HttpReply::Kind::kExport;
  reply.owner = c.p->name;
  reply.produce = [&d = c.api.d_, p = *c.p, course = *course, cohort = *cohort,
                   f = *format](const std::function<bool(std::string_view)>& sink) {
    return ExportProgress(d, p, course, cohort, f, sink);
  };
  const bool csv = *format == db::ExportFormat::kCsv;
  reply.content_type = csv ? "text/csv; charset=utf-8" : "application/x-ndjson";
  reply.filename =
      std::string("vsurg-progress") + (*format == db::ExportFormat::kXapi ? "-xapi.jsonl"
                                       : csv                              ? ".csv"
                                                                          : ".jsonl");
  return reply;
}

}  // namespace vsurg::server::http
