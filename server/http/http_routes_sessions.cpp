// The dashboard's routes for who is signed in, the scenes, sessions, their records and live
// events.
#include <nlohmann/json.hpp>

#include "common/core/time.h"
#include "common/scoring/report_json.h"
#include "common/scoring/vocabulary.h"
#include "common/sim/guidance.h"
#include "db/vocabulary.h"
#include "server/domain/scene_catalog.h"
#include "server/domain/training.h"
#include "server/http/http_reply.h"
#include "server/http/http_routes.h"
#include "server/http/http_views.h"
#include "server/ops/metrics.h"

namespace vsurg::server::http {

// --- The routes: one short function each, after its caller was authorised for its method. ---

HttpReply HttpApi::Routes::Me(const Call& c) {
  return Ok({{"user", c.p->name},
             {"role", db::RoleName(c.p->role)},
             {"group", c.p->group},
             {"csrf", c.web ? c.web->csrf : ""}});
}

// The Prometheus scrape: every collector the process registered, in the text format.
HttpReply HttpApi::Routes::Metrics(const Call& c) {
  return c.api.MetricsReply();
}

HttpReply HttpApi::Routes::Scenes(const Call& c) {
  auto listing = ListScenes(c.api.d_, *c.p);
  if (!listing.ok()) return ErrorReply(listing.error());
  json scenes = json::array();
  for (const SceneInfo& s : listing->scenes)
    scenes.push_back({{"name", s.name},
                      {"description", s.description},
                      {"model", s.model},
                      {"task", s.task},
                      {"error_budget_rms", s.error_budget_rms},
                      {"material", s.material},
                      {"limb", s.limb},
                      {"target", s.target},
                      {"tolerance", s.tolerance},
                      {"target_unit", s.task == "twist" ? "deg" : "mm"},
                      {"force_limit_n", s.force_limit_n},
                      {"device_max_force_n", s.device_max_force_n},
                      {"time_limit_s", s.time_limit_s},
                      {"hold_s", s.spec.hold_s}});
  return Ok({{"scenes", scenes}, {"unusable", listing->unusable}});
}

HttpReply HttpApi::Routes::SessionsList(const Call& c) {
  auto list =
      ListSessions(c.api.d_, *c.p, Param(c.query, "trainee"), Param(c.query, "live") == "1");
  if (!list.ok()) return ErrorReply(list.error());
  json out = json::array();
  for (const SessionView& v : *list) out.push_back(ViewJson(v));
  return Ok({{"sessions", out}});
}

HttpReply HttpApi::Routes::SessionCreate(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto trainee = Field<std::string>(*body, "trainee", "");
  auto scene = Field<std::string>(*body, "scene", "");
  if (!trainee.ok()) return ErrorReply(trainee.error());
  if (!scene.ok()) return ErrorReply(scene.error());
  auto exercise = Field<int64_t>(*body, "exercise", 0);
  if (!exercise.ok()) return ErrorReply(exercise.error());
  return c.api.OnNodeWorker(
      *c.p, [&d = c.api.d_, p = *c.p, trainee = *trainee, scene = *scene, exercise = *exercise] {
        auto created = exercise != 0 ? CreateExerciseSession(d, p, trainee, exercise)
                                     : CreateSession(d, p, trainee, scene);
        if (!created.ok()) return ErrorReply(created.error());
        // The station's key is not sent here: the trainee's station joins with its own token.
        return Json(201, {{"session", RecordJson(created->record)}});
      });
}

HttpReply HttpApi::Routes::SessionGet(const Call& c) {
  auto v = GetSessionWithTargets(c.api.d_, *c.p, c.id);
  if (!v.ok()) return ErrorReply(v.error());
  json j = ViewJson(v->view);
  // An attempt at a course's exercise: its checks against the targets.
  if (const auto& t = v->targets)
    j["targets"] = {{"passed", t->passed}, {"checks", ChecksJson(*t)}};
  return Ok(j);
}

HttpReply HttpApi::Routes::SessionStop(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto reason = Field<std::string>(*body, "reason", "stopped from the dashboard");
  if (!reason.ok()) return ErrorReply(reason.error());
  return c.api.OnNodeWorker(*c.p, [&d = c.api.d_, p = *c.p, id = c.id, reason = *reason] {
    auto v = StopSession(d, p, id, reason);
    if (!v.ok()) return ErrorReply(v.error());
    return Ok(ViewJson(*v));
  });
}

HttpReply HttpApi::Routes::SessionSurface(const Call& c) {
  return c.api.OnNodeWorker(*c.p, [&d = c.api.d_, p = *c.p, id = c.id] {
    auto surface = server::SessionSurface(d, p, id);
    if (!surface.ok()) return ErrorReply(surface.error());
    return Ok(
        {{"positions_mm", Millimetres(surface->positions)}, {"triangles", surface->triangles}});
  });
}

HttpReply HttpApi::Routes::SessionTraceRoute(const Call& c) {
  return c.api.OnNodeWorker(*c.p, [&d = c.api.d_, p = *c.p, id = c.id] {
    auto trace = SessionTrace(d, p, id);
    if (!trace.ok()) return ErrorReply(trace.error());
    HttpReply reply;
    reply.body = std::move(trace).value();  // the recorder's JSON as stored
    return reply;
  });
}

namespace {

// Who is in a live session and what the instructor asked for (common/sim/guidance.h): the
// dominance requested and the one the haptic path has ramped to so far.
json GuidanceJson(const SessionGuidance& g) {
  return {{"trainee", g.trainee},
          {"instructor", g.instructor.empty() ? json(nullptr) : json(g.instructor)},
          {"mode", sim::GuideModeName(g.requested.mode)},
          {"alpha_requested", g.requested.alpha},
          {"dominance_ratio", g.alpha}};
}

}  // namespace

HttpReply HttpApi::Routes::SessionGuidanceRoute(const Call& c) {
  auto g = GetGuidance(c.api.d_, *c.p, c.id);
  if (!g.ok()) return ErrorReply(g.error());
  return Ok(GuidanceJson(*g));
}

// The instructor whose station joined the session switches its mode from the dashboard:
// {"mode": "observe" | "guide" | "none" (leave), "alpha": 0..1 (guide only)}.
HttpReply HttpApi::Routes::SessionGuide(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto mode_name = Field<std::string>(*body, "mode", "");
  if (!mode_name.ok()) return ErrorReply(mode_name.error());
  auto alpha = Field<double>(*body, "alpha", 0.0);
  if (!alpha.ok()) return ErrorReply(alpha.error());
  auto mode = sim::ParseGuideMode(*mode_name);
  if (!mode.ok()) return ErrorReply(mode.error());
  auto g = GuideSession(c.api.d_, *c.p, c.id, {*mode, *alpha});
  if (!g.ok()) return ErrorReply(g.error());
  return Ok(GuidanceJson(*g));
}

HttpReply HttpApi::Routes::SessionFeedbackRoute(const Call& c) {
  auto rows = SessionFeedback(c.api.d_, *c.p, c.id);
  if (!rows.ok()) return ErrorReply(rows.error());
  json ratings = json::array();
  for (const db::SubmittedRow& s : *rows) {
    json r = {{"id", s.id},
              {"evaluator_group", s.evaluator_group},
              {"moment_min", s.moment_min ? json(*s.moment_min) : json(nullptr)},
              {"submitted", Iso(s.submitted_us)},
              {"scores", s.scores},
              {"comment", s.comment}};
    if (!s.evaluator.empty()) r["evaluator"] = s.evaluator;
    ratings.push_back(std::move(r));
  }
  return Ok({{"ratings", ratings}});
}

// Ended sessions as records, newest first: ?trainee= &scene= &q= (a part of the trainee's or
// the scene's name) &from= &to= (ISO times or
// microseconds) &min_score= &max_score= &page= (from 1) &per_page= (1..100, 25).
HttpReply HttpApi::Routes::Records(const Call& c) {
  db::SessionQuery q;
  if (auto v = Param(c.query, "trainee"); !v.empty()) q.trainee = v;
  if (auto v = Param(c.query, "scene"); !v.empty()) q.scene = v;
  if (auto v = Param(c.query, "q"); !v.empty()) q.search = v;
  for (auto [name, field] : {std::pair{"from", &q.from_us}, std::pair{"to", &q.to_us}}) {
    const auto t = QueryTime(c.query, name);
    if (!t) return ErrorReply(InvalidArgument(name, "an ISO time or microseconds"));
    if (*t != 0) *field = *t;
  }
  for (auto [name, field] :
       {std::pair{"min_score", &q.min_score}, std::pair{"max_score", &q.max_score}}) {
    const std::string v = Param(c.query, name);
    if (v.empty()) continue;
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (end != v.c_str() + v.size() || !(x >= 0 && x <= 10))
      return ErrorReply(InvalidArgument(name, "a score within 0..10"));
    *field = x;
  }
  auto count = [&](const char* name, int fallback, int max) -> std::optional<int> {
    const std::string v = Param(c.query, name);
    if (v.empty()) return fallback;
    const auto n = ParseId(v);
    if (!n || *n < 1 || *n > static_cast<uint64_t>(max)) return std::nullopt;
    return static_cast<int>(*n);
  };
  const auto page = count("page", 1, 100000), per_page = count("per_page", 25, 100);
  if (!page) return ErrorReply(InvalidArgument("page", "a page number from 1"));
  if (!per_page) return ErrorReply(InvalidArgument("per_page", "within 1..100"));
  q.limit = *per_page;
  q.offset = (*page - 1) * *per_page;
  auto found = FindSessions(c.api.d_, *c.p, q);
  if (!found.ok()) return ErrorReply(found.error());
  json rows = json::array();
  for (const db::SessionRow& r : found->rows) {
    json j = RecordJson(r.record);
    j["score"] = r.score ? json(*r.score) : json(nullptr);
    j["completed"] = r.completed;
    j["has_record"] = r.has_trace;
    rows.push_back(std::move(j));
  }
  return Ok(
      {{"sessions", rows}, {"total", found->total}, {"page", *page}, {"per_page", *per_page}});
}

// The subjects of a kind anyone has rated (?kind=session|trainee|model): what a report can be
// asked for, chosen from a list instead of typed.
HttpReply HttpApi::Routes::Subjects(const Call& c) {
  auto subjects = RatedSubjects(c.api.d_, *c.p, Param(c.query, "kind"));
  if (!subjects.ok()) return ErrorReply(subjects.error());
  return Ok({{"subjects", *subjects}});
}

// An event stream: one session's (10 Hz, with its surface) or every live session's (4 Hz).
HttpReply HttpApi::Routes::Events(const Call& c, uint64_t session, double max_hz) {
  auto hz = CheckWatch(c.api.d_, *c.p, session, max_hz);
  if (!hz.ok()) return ErrorReply(hz.error());
  HttpReply reply;
  reply.kind = HttpReply::Kind::kEvents;
  reply.watch = {session, *hz, session != 0};
  reply.still_allowed = c.api.StillAllowed(c.authorization, c.web);
  return reply;
}
HttpReply HttpApi::Routes::SessionEvents(const Call& c) {
  return Events(c, c.id, 10);
}
HttpReply HttpApi::Routes::LiveEvents(const Call& c) {
  return Events(c, 0, 4);
}

}  // namespace vsurg::server::http
