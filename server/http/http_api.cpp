#include "server/http/http_api.h"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string_view>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/core/log.h"
#include "common/core/realtime.h"
#include "common/core/time.h"
#include "common/scoring/report_json.h"
#include "common/scoring/vocabulary.h"
#include "db/vocabulary.h"
#include "server/domain/scene_catalog.h"
#include "server/domain/training.h"
#include "server/http/web_assets.h"
#include "server/ops/metrics.h"

namespace vsurg::server::http {
namespace {

using nlohmann::json;
constexpr std::string_view kCookie = "vsurg_session";

HttpReply Json(int status, const json& j) {
  HttpReply r;
  r.status = status;
  r.body = j.dump(-1, ' ', false, json::error_handler_t::replace);
  return r;
}

HttpReply Ok(const json& j) {
  return Json(200, j);
}

HttpReply NoContent() {
  HttpReply r;
  r.status = 204;
  r.content_type.clear();
  return r;
}

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

// Positions in metres as one flat array of millimetres to 0.01 mm (x, y, z, x, …): the form the
// page's 3D view reads for the rest surface and for the moved vertices alike.
json Millimetres(const std::vector<geometry::Vec3>& positions) {
  json out = json::array();
  for (const geometry::Vec3& p : positions)
    for (int k = 0; k < 3; ++k) out.push_back(std::round(Finite(p[k]) * 1e5) / 100.0);
  return out;
}

// The first value of a query parameter, or "".
std::string Param(const std::multimap<std::string, std::string>& q, const std::string& name) {
  const auto it = q.find(name);
  return it == q.end() ? std::string() : it->second;
}

std::optional<uint64_t> ParseId(std::string_view s) {
  if (s.empty() || s.size() > 19) return std::nullopt;
  uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return std::nullopt;
    v = v * 10 + static_cast<uint64_t>(c - '0');
  }
  return v;
}

// A query parameter as a non-negative 64-bit number: 0 when absent, nullopt when malformed.
std::optional<int64_t> QueryNumber(const std::multimap<std::string, std::string>& q,
                                   const char* name) {
  const std::string v = Param(q, name);
  if (v.empty()) return 0;
  const auto id = ParseId(v);
  if (!id || *id > static_cast<uint64_t>(INT64_MAX)) return std::nullopt;
  return static_cast<int64_t>(*id);
}

// A time parameter: an ISO time (2026-11-22T10:00:00Z) or microseconds since the epoch; 0 when
// absent, nullopt when neither.
std::optional<int64_t> QueryTime(const std::multimap<std::string, std::string>& q,
                                 const char* name) {
  const std::string v = Param(q, name);
  if (v.empty()) return 0;
  if (auto iso = ParseIsoUtc(v, name); iso.ok()) return *iso;
  return QueryNumber(q, name);
}

// Splits "/a/b/c" into {"a", "b", "c"}.
std::vector<std::string_view> Segments(std::string_view path) {
  std::vector<std::string_view> out;
  while (!path.empty()) {
    if (path.front() == '/') {
      path.remove_prefix(1);
      continue;
    }
    const size_t slash = path.find('/');
    out.push_back(path.substr(0, slash));
    if (slash == std::string_view::npos) break;
    path.remove_prefix(slash);
  }
  return out;
}

// A JSON object body (POST with Content-Type application/json); an empty body is {}.
Expected<json> Body(const HttpRequest& r) {
  if (r.body.empty()) return json::object();
  const std::string type = r.content_type.substr(0, r.content_type.find(';'));
  if (type != "application/json")
    return Error{ErrorCode::kInvalidArgument, "the body must be application/json", "content-type"};
  json j = json::parse(r.body, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    return Error{ErrorCode::kParseError, "the body is not a JSON object", "body"};
  return j;
}

template <class T>
const Error* Err(const Expected<T>& x) {
  return x.ok() ? nullptr : &x.error();
}

template <class T>
Expected<T> Field(const json& j, const char* name, T fallback) {
  const auto it = j.find(name);
  if (it == j.end() || it->is_null()) return fallback;
  try {
    return it->get<T>();
  } catch (const json::exception&) {
    return InvalidArgument(name, std::string("has the wrong type"));
  }
}

std::string PageRole(std::string_view page, Method& m) {
  if (page == "live") return m = Method::kMonitorWatch, "instructor";
  // A session's page and the records: whoever may read sessions (a trainee their own; the API
  // says which).
  if (page == "session") return m = Method::kSessionGet, "any signed-in user";
  if (page == "records") return m = Method::kSessionList, "any signed-in user";
  if (page == "evaluate") return m = Method::kEvaluationSubmit, "evaluator";
  if (page == "reports") return m = Method::kEvaluationReport, "instructor or evaluator";
  if (page == "admin") return m = Method::kAdminListUsers, "administrator";
  if (page == "mine") return m = Method::kSessionList, "trainee";
  if (page == "training") return m = Method::kTrainingCreateCohort, "instructor";
  return "";
}

HttpReply Html(int status, std::string body) {
  HttpReply r;
  r.status = status;
  r.content_type = "text/html; charset=utf-8";
  r.body = std::move(body);
  return r;
}

HttpReply Redirect(const std::string& to) {
  HttpReply r;
  r.status = 303;
  r.content_type.clear();
  r.headers.emplace_back("Location", to);
  return r;
}

// The page shell with its name filled in (a constant from PageRole, never request text).
HttpReply Shell(const std::string& page) {
  const auto shell = FindAsset("/index.html");
  std::string body(shell ? shell->body : "");
  const std::string mark = "{{PAGE}}";
  for (size_t at = body.find(mark); at != std::string::npos; at = body.find(mark))
    body.replace(at, mark.size(), page);
  HttpReply r = Html(200, std::move(body));
  r.headers.emplace_back("Cache-Control", "no-store");
  return r;
}

// --- the training programme's JSON (server/domain/training.h) ---

json FiniteOrNull(double x) {
  return std::isfinite(x) ? json(x) : json(nullptr);
}

// A task in the units a trainee reads (degrees of twist or millimetres of press depth).
json TaskJson(const scoring::TaskSpec& t) {
  const scoring::TaskDisplayUnit unit = scoring::DisplayUnitOf(t.kind);
  return {{"kind", t.kind == scoring::TaskKind::kTwist ? "twist" : "press"},
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

// `compact`: the grid's cells (state and counts only; 2,000 of them for 200 trainees).
json TraineeProgressJson(const TraineeProgress& t, bool compact = false) {
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

}  // namespace

std::optional<std::string> UrlDecode(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (c == '+') {
      out += ' ';
    } else if (c == '%') {
      if (i + 2 >= s.size()) return std::nullopt;
      int v = 0;
      for (int k = 1; k <= 2; ++k) {
        const char h = s[i + k];
        v <<= 4;
        if (h >= '0' && h <= '9')
          v |= h - '0';
        else if (h >= 'a' && h <= 'f')
          v |= h - 'a' + 10;
        else if (h >= 'A' && h <= 'F')
          v |= h - 'A' + 10;
        else
          return std::nullopt;
      }
      out += static_cast<char>(v);
      i += 2;
    } else {
      out += c;
    }
  }
  return out;
}

std::optional<std::multimap<std::string, std::string>> ParseQuery(std::string_view q) {
  std::multimap<std::string, std::string> out;
  while (!q.empty()) {
    const size_t amp = q.find('&');
    const std::string_view pair = q.substr(0, amp);
    q = amp == std::string_view::npos ? std::string_view() : q.substr(amp + 1);
    if (pair.empty()) continue;
    const size_t eq = pair.find('=');
    auto name = UrlDecode(pair.substr(0, eq));
    auto value = UrlDecode(eq == std::string_view::npos ? "" : pair.substr(eq + 1));
    if (!name || !value) return std::nullopt;
    out.emplace(std::move(*name), std::move(*value));
  }
  return out;
}

int HttpApi::StatusFor(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
    case ErrorCode::kParseError:
      return 400;
    case ErrorCode::kUnauthenticated:
      return 401;
    case ErrorCode::kPermissionDenied:
      return 403;
    case ErrorCode::kNotFound:
      return 404;
    case ErrorCode::kAlreadyExists:
    case ErrorCode::kFailedPrecondition:
      return 409;
    case ErrorCode::kResourceExhausted:
      return 429;
    case ErrorCode::kUnavailable:
      return 503;
    case ErrorCode::kIoError:
    case ErrorCode::kNumerical:
      return 500;
  }
  return 500;
}

HttpReply HttpApi::ErrorReply(const Error& e) {
  return Json(StatusFor(e.code), {{"error", e.message}, {"field", e.field}});
}

std::string HttpApi::TelemetryJson(const SessionTelemetry& t, bool with_surface) {
  const sim::Telemetry& s = t.sim;
  json j = {{"id", t.id},
            {"trainee", t.trainee},
            {"scene", t.scene},
            {"state", SessionStateName(t.state)},
            {"force_vector_n", {Finite(s.force.x()), Finite(s.force.y()), Finite(s.force.z())}}};
  for (const sim::TelemetryField& f : sim::TelemetryFields(t)) {
    const std::string name(f.name);
    switch (f.kind) {
      case sim::TelemetryField::Kind::kReal:
        j[name] = Finite(f.value);
        break;
      case sim::TelemetryField::Kind::kCount:
        j[name] = static_cast<uint64_t>(f.value);
        break;
      case sim::TelemetryField::Kind::kFlag:
        j[name] = f.value != 0;
        break;
    }
  }
  if (with_surface && t.has_surface) {
    j["surface"] = {{"frame", t.surface_frame},
                    {"indices", t.surface_indices},
                    {"positions_mm", Millimetres(t.surface_positions)}};
  }
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

HttpReply HttpApi::Deferred(FairWorkers* workers, const db::Principal& p,
                            std::function<HttpReply()> work, const char* busy) {
  if (!workers) return work();  // no workers configured: on the caller's thread
  HttpReply reply;
  reply.kind = HttpReply::Kind::kDeferred;
  reply.deferred = [workers, busy, user = p.name,
                    work = std::move(work)](std::function<void(HttpReply)> done) {
    const FairWorkers::Posted posted = workers->Post(user, [work, done](bool run) {
      done(run ? work() : ErrorReply(Error{ErrorCode::kUnavailable, "the server is stopping", ""}));
    });
    switch (posted) {
      case FairWorkers::Posted::kQueued:
        return;
      case FairWorkers::Posted::kUserBusy:  // this user's own share is taken: 429, theirs alone
        done(ErrorReply(Error{ErrorCode::kResourceExhausted,
                              "you have too many of these requests waiting; wait for their answers",
                              ""}));
        return;
      case FairWorkers::Posted::kFull:
      case FairWorkers::Posted::kStopping:
        done(ErrorReply(Error{ErrorCode::kUnavailable, busy, ""}));
        return;
    }
  };
  return reply;
}

HttpReply HttpApi::OffThread(const db::Principal& p, std::function<HttpReply()> work) {
  return Deferred(reads_.get(), p, std::move(work),
                  "too many long reads at once; try again shortly");
}

HttpReply HttpApi::OnNodeWorker(const db::Principal& p, std::function<HttpReply()> work) {
  return Deferred(node_calls_.get(), p, std::move(work),
                  "too many calls waiting on simulation nodes; try again shortly");
}

HttpApi::~HttpApi() = default;

HttpApi::HttpApi(Domain& domain, const HttpApiOptions& options)
    : d_(domain),
      options_(options),
      clock_(options.clock ? *options.clock : DefaultClock()),
      reads_(options.read_workers > 0 ? std::make_unique<FairWorkers>(FairWorkersOptions{
                                            .workers = options.read_workers,
                                            .max_queued = options.max_queued_reads,
                                            .per_user_queued = options.per_user_queued_reads,
                                            .thread_name = "vsurg-http-read"})
                                      : nullptr),
      node_calls_(options.node_workers > 0 ? std::make_unique<FairWorkers>(FairWorkersOptions{
                                                 .workers = options.node_workers,
                                                 .max_queued = options.max_queued_node_calls,
                                                 .per_user_queued = options.per_user_queued_reads,
                                                 .thread_name = "vsurg-http-node"})
                                           : nullptr),
      sessions_(clock_, options.session_ttl_s),
      limiter_(clock_, options.sign_in_failures),
      bearer_limiter_(clock_, options.bearer_failures) {}

std::function<bool()> HttpApi::StillAllowed(const std::string& authorization,
                                            const std::optional<WebSession>& web) {
  std::string id = web ? web->id : std::string();
  return [this, authorization, id] {
    if (!id.empty() && !sessions_.Find(id)) return false;  // signed out (or expired)
    return Authorize(d_.store, authorization, Method::kMonitorWatch).ok();
  };
}

// What a route's handler gets: the request, the caller (authorised for the route's method) and
// the pattern's parameters.
struct HttpApi::Call {
  HttpApi& api;
  const HttpRequest& r;
  const std::multimap<std::string, std::string>& query;
  const std::optional<WebSession>& web;
  const std::string& authorization;
  const db::Principal* p = nullptr;
  uint64_t id = 0;   // {id}
  std::string name;  // {name}, decoded
};

// The handlers, one per route (kRoutes below); private to this file.
struct HttpApi::Routes {
  static HttpReply Me(const Call& c);
  static HttpReply Scenes(const Call& c);
  static HttpReply Metrics(const Call& c);
  static HttpReply SessionsList(const Call& c);
  static HttpReply SessionCreate(const Call& c);
  static HttpReply SessionGet(const Call& c);
  static HttpReply SessionStop(const Call& c);
  static HttpReply SessionSurface(const Call& c);
  static HttpReply SessionTraceRoute(const Call& c);
  static HttpReply SessionFeedbackRoute(const Call& c);
  static HttpReply Records(const Call& c);
  static HttpReply Subjects(const Call& c);
  static HttpReply Events(const Call& c, uint64_t session, double max_hz);
  static HttpReply SessionEvents(const Call& c);
  static HttpReply LiveEvents(const Call& c);
  static HttpReply EvaluationsMine(const Call& c);
  static HttpReply EvaluationSubmit(const Call& c);
  static HttpReply Reports(const Call& c);
  static HttpReply TrainingEffectRoute(const Call& c);
  static HttpReply WeightSetsList(const Call& c);
  static HttpReply WeightSetPut(const Call& c);
  static HttpReply WeightSetGet(const Call& c);
  static HttpReply UsersList(const Call& c);
  static HttpReply UserCreate(const Call& c);
  static HttpReply UserToken(const Call& c);
  static HttpReply UserRevoke(const Call& c);
  static HttpReply UserDisabled(const Call& c);
  static HttpReply Export(const Call& c);
  static HttpReply BackupRoute(const Call& c);
  // The training programme (server/domain/training.h).
  static HttpReply Courses(const Call& c);
  static HttpReply CourseCreate(const Call& c);
  static HttpReply CourseGet(const Call& c);
  static HttpReply ExerciseSpecPut(const Call& c);
  static HttpReply Cohorts(const Call& c);
  static HttpReply CohortCreate(const Call& c);
  static HttpReply CohortMembers(const Call& c);
  static HttpReply CohortGrid(const Call& c);
  static HttpReply CohortCurveRoute(const Call& c);
  static HttpReply CohortCurveReply(Domain& d, const db::Principal& p, uint64_t cohort,
                                    int64_t exercise);
  static HttpReply EnrolRoute(const Call& c);
  static HttpReply Experts(const Call& c);
  static HttpReply ExpertSet(const Call& c);
  static HttpReply TrainingMine(const Call& c);
  static HttpReply TrainingCurve(const Call& c);
  static HttpReply TrainingNext(const Call& c);
  static HttpReply TrainingExport(const Call& c);
};

HttpReply HttpApi::Handle(const HttpRequest& r) {
  const size_t q = r.target.find('?');
  const std::string path = r.target.substr(0, q);
  auto query = ParseQuery(q == std::string::npos ? std::string_view()
                                                 : std::string_view(r.target).substr(q + 1));
  if (!query || path.empty() || path.front() != '/')
    return ErrorReply(InvalidArgument("target", "a malformed request target"));
  if (options_.metrics_only && path != "/api/v1/metrics")
    return ErrorReply(Error{ErrorCode::kNotFound,
                            "a simulation node serves only /api/v1/metrics here; the dashboard "
                            "is the control plane's",
                            "path"});
  if (path.rfind("/api/v1/", 0) == 0) return Api(r, path.substr(7), *query);
  if (path.rfind("/static/", 0) == 0) {
    const auto asset = FindAsset(path.substr(7));
    if (!asset || r.method != "GET")
      return ErrorReply(Error{ErrorCode::kNotFound, "no such file", "path"});
    HttpReply reply;
    reply.content_type = asset->type;
    reply.body.assign(asset->body);
    reply.headers.emplace_back("Cache-Control", "no-cache");
    return reply;
  }
  return Page(r, path);
}

HttpReply HttpApi::Page(const HttpRequest& r, const std::string& path) {
  if (r.method != "GET" && r.method != "HEAD")
    return ErrorReply(Error{ErrorCode::kNotFound, "no such page", "path"});
  const auto seg = Segments(path);
  if (!seg.empty() && seg[0] == "signin" && seg.size() == 1) return Shell("signin");
  std::string page = seg.empty() ? "" : std::string(seg[0]);
  // Who is signed in (pages use the cookie only).
  std::optional<db::Principal> who;
  if (auto id = CookieValue(r.cookie, kCookie))
    if (auto web = sessions_.Find(*id)) {
      auto p = d_.store.Authenticate(web->token);
      if (p.ok())
        who = *p;
      else
        sessions_.Remove(*id);
    }
  if (page.empty()) {
    if (!who) return Redirect("/signin");
    switch (who->role) {
      case db::Role::kTrainee:
        return Redirect("/mine");
      case db::Role::kEvaluator:
        return Redirect("/evaluate");
      case db::Role::kInstructor:
      case db::Role::kAdmin:
        return Redirect("/live");
    }
  }
  Method m{};
  const std::string role = PageRole(page, m);
  const bool shape_ok = role.empty()        ? false
                        : page == "session" ? seg.size() == 2 && ParseId(seg[1]).has_value()
                                            : seg.size() == 1;
  if (!shape_ok) return Html(404, "<!doctype html><title>Not found</title><p>No such page.</p>");
  if (!who) return Redirect("/signin?next=" + page);
  if (!Permit(*who, m).ok()) {
    // The page shell as on every page (the header, the menu, sign-out); app.js says why.
    HttpReply reply = Shell("forbidden");
    reply.status = 403;
    return reply;
  }
  return Shell(page);
}

HttpReply HttpApi::SignIn(const HttpRequest& r) {
  const double wait = limiter_.RetryAfter(r.remote);
  if (wait > 0) {
    HttpReply reply =
        ErrorReply(Error{ErrorCode::kResourceExhausted,
                         "too many failed sign-ins from this address; try later", ""});
    reply.headers.emplace_back("Retry-After", std::to_string(static_cast<int>(std::ceil(wait))));
    return reply;
  }
  auto body = Body(r);
  if (!body.ok()) return ErrorReply(body.error());
  auto token = Field<std::string>(*body, "token", "");
  if (!token.ok()) return ErrorReply(token.error());
  if (token->empty() || token->size() > 256) {
    limiter_.Failed(r.remote);
    return ErrorReply(Error{ErrorCode::kUnauthenticated, "a token is required", "token"});
  }
  auto p = d_.store.Authenticate(*token);
  if (!p.ok()) {
    if (p.error().code == ErrorCode::kUnavailable) return ErrorReply(p.error());
    limiter_.Failed(r.remote);
    return ErrorReply(Error{ErrorCode::kUnauthenticated, "unknown or revoked token", "token"});
  }
  const WebSession web = sessions_.Create(*token, p->name);
  HttpReply reply = Ok({{"user", p->name},
                        {"role", db::RoleName(p->role)},
                        {"group", p->group},
                        {"csrf", web.csrf},
                        {"expires_in_s", static_cast<int64_t>(sessions_.ttl_s())}});
  reply.headers.emplace_back(
      "Set-Cookie", std::string(kCookie) + "=" + web.id + "; Path=/; HttpOnly; SameSite=Strict; " +
                        "Max-Age=" + std::to_string(static_cast<int64_t>(sessions_.ttl_s())) +
                        (options_.secure_cookies ? "; Secure" : ""));
  return reply;
}

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

HttpReply HttpApi::MetricsReply() const {
  if (!options_.metrics)
    return ErrorReply(Error{ErrorCode::kNotFound, "this process keeps no metrics", ""});
  HttpReply r;
  r.content_type = "text/plain; version=0.0.4; charset=utf-8";
  r.body = options_.metrics->Render();
  r.headers.emplace_back("Cache-Control", "no-store");
  return r;
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
  auto v = GetSession(c.api.d_, *c.p, c.id);
  if (!v.ok()) return ErrorReply(v.error());
  json j = ViewJson(*v);
  // An attempt at a course's exercise: its checks against the targets.
  auto checks = SessionTargets(c.api.d_, *c.p, c.id);
  if (!checks.ok()) return ErrorReply(checks.error());
  if (*checks) j["targets"] = {{"passed", (*checks)->passed}, {"checks", ChecksJson(**checks)}};
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

HttpReply HttpApi::Routes::EvaluationsMine(const Call& c) {
  auto queue = ListOwnEvaluations(c.api.d_, *c.p, 200);
  if (!queue.ok()) return ErrorReply(queue.error());
  json sessions = json::array(), submitted = json::array();
  for (const db::SessionRecord& s : queue->sessions) sessions.push_back(RecordJson(s));
  for (const db::SubmittedRow& s : queue->submitted)
    submitted.push_back({{"id", s.id},
                         {"subject_kind", db::SubjectKindName(s.subject_kind)},
                         {"subject", s.subject},
                         {"moment_min", s.moment_min ? json(*s.moment_min) : json(nullptr)},
                         {"submitted", Iso(s.submitted_us)},
                         {"scores", s.scores},
                         {"comment", s.comment}});
  return Ok({{"sessions", sessions}, {"models", queue->models}, {"submitted", submitted}});
}

HttpReply HttpApi::Routes::EvaluationSubmit(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  SubmissionRequest in;
  auto key = Field<std::string>(*body, "idempotency_key", "");
  auto kind = Field<std::string>(*body, "subject_kind", "");
  auto subject = Field<std::string>(*body, "subject", "");
  auto evaluator = Field<std::string>(*body, "evaluator", "");
  auto group = Field<std::string>(*body, "evaluator_group", "");
  auto scores = Field<std::vector<double>>(*body, "scores", {});
  auto moment = Field<double>(*body, "moment_min", -1);
  auto comment = Field<std::string>(*body, "comment", "");
  for (const Error* e : {Err(key), Err(kind), Err(subject), Err(evaluator), Err(group), Err(scores),
                         Err(moment), Err(comment)})
    if (e) return ErrorReply(*e);
  in.comment = *comment;
  in.idempotency_key = *key;
  in.subject_kind = *kind;
  in.subject = *subject;
  in.evaluator = *evaluator;
  in.evaluator_group = *group;
  in.scores = *scores;
  if (body->contains("moment_min") && !(*body)["moment_min"].is_null()) in.moment_min = *moment;
  auto submission = PrepareSubmission(*c.p, in);
  if (!submission.ok()) return ErrorReply(submission.error());
  HttpReply reply;
  reply.kind = HttpReply::Kind::kDeferred;
  auto shared = std::make_shared<db::Submission>(std::move(submission).value());
  db::Store& store = c.api.d_.store;
  reply.deferred = [&store, shared](std::function<void(HttpReply)> done) {
    // Answers from the store's writer thread once the group commit is on disk.
    store.SubmitEvaluationAsync(*shared, [done](Expected<db::SubmitResult> res) {
      if (!res.ok()) return done(ErrorReply(res.error()));
      done(Json(res->duplicate ? 200 : 201, {{"submission_id", res->submission_id},
                                             {"submitted", Iso(res->submitted_us)},
                                             {"duplicate", res->duplicate}}));
    });
  };
  return reply;
}

HttpReply HttpApi::Routes::Reports(const Call& c) {
  std::vector<std::string> subjects;
  for (auto [it, end] = c.query.equal_range("subject"); it != end; ++it)
    subjects.push_back(it->second);
  auto report = Report(c.api.d_, *c.p, Param(c.query, "kind"), subjects, Param(c.query, "weights"));
  if (!report.ok()) return ErrorReply(report.error());
  HttpReply reply;
  reply.body = *report;
  return reply;
}

HttpReply HttpApi::Routes::TrainingEffectRoute(const Call& c) {
  auto cells = TrainingEffect(c.api.d_, *c.p, Param(c.query, "weights"));
  if (!cells.ok()) return ErrorReply(cells.error());
  HttpReply reply;
  reply.body = *cells;
  return reply;
}

HttpReply HttpApi::Routes::WeightSetsList(const Call& c) {
  auto names = ListWeightSets(c.api.d_, *c.p);
  if (!names.ok()) return ErrorReply(names.error());
  auto builtin = GetWeightSet(c.api.d_, *c.p, "");
  if (!builtin.ok()) return ErrorReply(builtin.error());
  json index_names = json::array(), groups = json::array();
  for (const char* name : scoring::kIndexNames) index_names.push_back(name);
  for (int g = 0; g < scoring::kGroupCount; ++g)
    groups.push_back(scoring::GroupName(static_cast<scoring::EvaluatorGroup>(g)));
  return Ok({{"names", *names},
             {"default", json::parse(*builtin)},
             {"index_names", index_names},
             {"groups", groups}});
}

HttpReply HttpApi::Routes::WeightSetPut(const Call& c) {
  auto body = Body(c.r);  // checks the type and that it is an object
  if (!body.ok()) return ErrorReply(body.error());
  if (Status s = PutWeightSet(c.api.d_, *c.p, c.r.body); !s.ok()) return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::WeightSetGet(const Call& c) {
  auto w = GetWeightSet(c.api.d_, *c.p, c.name);
  if (!w.ok()) return ErrorReply(w.error());
  HttpReply reply;
  reply.body = *w;
  return reply;
}

HttpReply HttpApi::Routes::UsersList(const Call& c) {
  auto users = ListUsers(c.api.d_, *c.p);
  if (!users.ok()) return ErrorReply(users.error());
  json out = json::array();
  for (const db::UserRecord& u : *users) out.push_back(UserJson(u));
  return Ok({{"users", out}});
}

HttpReply HttpApi::Routes::UserCreate(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto name = Field<std::string>(*body, "name", "");
  auto role = Field<std::string>(*body, "role", "");
  auto group = Field<std::string>(*body, "group", "");
  if (!name.ok()) return ErrorReply(name.error());
  if (!role.ok()) return ErrorReply(role.error());
  if (!group.ok()) return ErrorReply(group.error());
  auto u = CreateUser(c.api.d_, *c.p, *name, db::ParseRole(*role), *group);
  if (!u.ok()) return ErrorReply(u.error());
  return Json(201, UserJson(*u));
}

HttpReply HttpApi::Routes::UserToken(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto label = Field<std::string>(*body, "label", "dashboard");
  if (!label.ok()) return ErrorReply(label.error());
  auto token = IssueToken(c.api.d_, *c.p, c.name, *label);
  if (!token.ok()) return ErrorReply(token.error());
  HttpReply reply = Json(201, {{"user", c.name}, {"token", *token}});
  reply.headers.emplace_back("Cache-Control", "no-store");
  return reply;
}

HttpReply HttpApi::Routes::UserRevoke(const Call& c) {
  if (auto body = Body(c.r); !body.ok()) return ErrorReply(body.error());
  if (Status s = RevokeTokens(c.api.d_, *c.p, c.name); !s.ok()) return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::UserDisabled(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto disabled = Field<bool>(*body, "disabled", true);
  if (!disabled.ok()) return ErrorReply(disabled.error());
  if (Status s = SetDisabled(c.api.d_, *c.p, c.name, *disabled); !s.ok())
    return ErrorReply(s.error());
  return NoContent();
}

HttpReply HttpApi::Routes::Export(const Call& c) {
  const auto from = QueryTime(c.query, "from"), to = QueryTime(c.query, "to");
  const auto session = QueryNumber(c.query, "session");
  if (!from) return ErrorReply(InvalidArgument("from", "an ISO time or microseconds"));
  if (!to) return ErrorReply(InvalidArgument("to", "an ISO time or microseconds"));
  if (!session) return ErrorReply(InvalidArgument("session", "a session id"));
  auto plan = PlanExport(*c.p, Param(c.query, "format"), *from, *to, Param(c.query, "trainee"),
                         static_cast<uint64_t>(*session));
  if (!plan.ok()) return ErrorReply(plan.error());
  HttpReply reply;
  reply.kind = HttpReply::Kind::kExport;
  reply.export_plan = *plan;
  reply.owner = c.p->name;
  const bool csv = plan->format == db::ExportFormat::kCsv;
  reply.content_type = csv ? "text/csv; charset=utf-8" : "application/x-ndjson";
  reply.filename = plan->format == db::ExportFormat::kCsv    ? "vsurg-evaluations.csv"
                   : plan->format == db::ExportFormat::kXapi ? "vsurg-evaluations-xapi.jsonl"
                                                             : "vsurg-evaluations.jsonl";
  return reply;
}

HttpReply HttpApi::Routes::BackupRoute(const Call& c) {
  auto body = Body(c.r);
  if (!body.ok()) return ErrorReply(body.error());
  auto name = Field<std::string>(*body, "name", "");
  if (!name.ok()) return ErrorReply(name.error());
  if (Status s = Backup(c.api.d_, *c.p, *name); !s.ok()) return ErrorReply(s.error());
  return Json(201, {{"backup", *name}});
}

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

const HttpApi::Route HttpApi::kRoutes[] = {
    {"GET", "me", Method::kSessionListScenes, &Routes::Me},  // every role
    {"GET", "scenes", Method::kSessionListScenes, &Routes::Scenes},
    {"GET", "metrics", Method::kOpsMetrics, &Routes::Metrics},
    {"GET", "sessions", Method::kSessionList, &Routes::SessionsList},
    {"POST", "sessions", Method::kSessionCreate, &Routes::SessionCreate},
    {"GET", "sessions/{id}", Method::kSessionGet, &Routes::SessionGet},
    {"POST", "sessions/{id}/stop", Method::kSessionStop, &Routes::SessionStop},
    {"GET", "sessions/{id}/surface", Method::kMonitorWatch, &Routes::SessionSurface},
    {"GET", "sessions/{id}/events", Method::kMonitorWatch, &Routes::SessionEvents},
    {"GET", "sessions/{id}/trace", Method::kSessionGet, &Routes::SessionTraceRoute},
    {"GET", "sessions/{id}/feedback", Method::kSessionGet, &Routes::SessionFeedbackRoute},
    {"GET", "records", Method::kSessionList, &Routes::Records},
    {"GET", "subjects", Method::kEvaluationReport, &Routes::Subjects},
    {"GET", "live/events", Method::kMonitorWatch, &Routes::LiveEvents},
    {"GET", "evaluations/mine", Method::kEvaluationSubmit, &Routes::EvaluationsMine},
    {"POST", "evaluations", Method::kEvaluationSubmit, &Routes::EvaluationSubmit},
    {"GET", "reports", Method::kEvaluationReport, &Routes::Reports},
    {"GET", "training-effect", Method::kEvaluationTrainingEffect, &Routes::TrainingEffectRoute},
    {"GET", "weight-sets", Method::kAdminListWeightSets, &Routes::WeightSetsList},
    {"POST", "weight-sets", Method::kAdminPutWeightSet, &Routes::WeightSetPut},
    {"GET", "weight-sets/{name}", Method::kAdminListWeightSets, &Routes::WeightSetGet},
    {"GET", "users", Method::kAdminListUsers, &Routes::UsersList},
    {"POST", "users", Method::kAdminCreateUser, &Routes::UserCreate},
    {"POST", "users/{name}/token", Method::kAdminIssueToken, &Routes::UserToken},
    {"POST", "users/{name}/revoke", Method::kAdminRevokeTokens, &Routes::UserRevoke},
    {"POST", "users/{name}/disabled", Method::kAdminSetDisabled, &Routes::UserDisabled},
    {"GET", "export", Method::kAdminExport, &Routes::Export},
    {"POST", "backup", Method::kAdminBackup, &Routes::BackupRoute},
    {"GET", "training/courses", Method::kTrainingListCourses, &Routes::Courses},
    {"POST", "training/courses", Method::kTrainingCreateCourse, &Routes::CourseCreate},
    {"GET", "training/courses/{id}", Method::kTrainingListCourses, &Routes::CourseGet},
    {"POST", "training/exercises/{id}/spec", Method::kTrainingUpdateExercise,
     &Routes::ExerciseSpecPut},
    {"GET", "training/cohorts", Method::kTrainingListCohorts, &Routes::Cohorts},
    {"POST", "training/cohorts", Method::kTrainingCreateCohort, &Routes::CohortCreate},
    {"POST", "training/cohorts/{id}/members", Method::kTrainingAddMembers, &Routes::CohortMembers},
    {"GET", "training/cohorts/{id}/grid", Method::kTrainingProgress, &Routes::CohortGrid},
    {"GET", "training/cohorts/{id}/curve", Method::kTrainingProgress, &Routes::CohortCurveRoute},
    {"POST", "training/enrolments", Method::kTrainingEnrol, &Routes::EnrolRoute},
    {"GET", "training/experts", Method::kTrainingSetExpert, &Routes::Experts},
    {"POST", "training/experts", Method::kTrainingSetExpert, &Routes::ExpertSet},
    {"GET", "training/mine", Method::kTrainingProgress, &Routes::TrainingMine},
    {"GET", "training/curve", Method::kTrainingCurve, &Routes::TrainingCurve},
    {"GET", "training/next", Method::kTrainingNext, &Routes::TrainingNext},
    {"GET", "training/export", Method::kTrainingProgress, &Routes::TrainingExport},
};

HttpReply HttpApi::Api(const HttpRequest& r, const std::string& path,
                       const std::multimap<std::string, std::string>& query) {
  const auto seg = Segments(path);
  const bool get = r.method == "GET" || r.method == "HEAD";
  const bool post = r.method == "POST";
  if (!get && !post)
    return ErrorReply(Error{ErrorCode::kInvalidArgument, "method not allowed", "method"});
  if (seg.size() == 1 && seg[0] == "signin" && post) return SignIn(r);

  // Authentication: a bearer header (scripts), else the cookie (pages). Then CSRF for writes.
  // Tokens are 256-bit secrets, so guessing one is hopeless; failures are still counted, logged
  // and limited per address (bearer_failures a minute), as sign-ins are.
  std::optional<WebSession> web;
  std::string authorization = r.authorization;
  const bool bearer = !authorization.empty();
  if (bearer) {
    if (const double wait = bearer_limiter_.RetryAfter(r.remote); wait > 0) {
      HttpReply reply = ErrorReply(Error{
          ErrorCode::kResourceExhausted,
          "too many requests with unknown tokens from this address; try later", "authorization"});
      reply.headers.emplace_back("Retry-After", std::to_string(static_cast<int>(std::ceil(wait))));
      return reply;
    }
    // Prometheus' token: the scrape, nothing else (every other route treats it as unknown).
    if (get && seg.size() == 1 && seg[0] == "metrics" && !options_.metrics_token.empty() &&
        SameSecret(authorization, "Bearer " + options_.metrics_token))
      return MetricsReply();
  } else {
    if (auto id = CookieValue(r.cookie, kCookie)) web = sessions_.Find(*id);
    if (!web) return ErrorReply(Error{ErrorCode::kUnauthenticated, "sign in first", "session"});
    authorization = "Bearer " + web->token;
    if (post && !SameSecret(r.csrf, web->csrf))
      return ErrorReply(Error{ErrorCode::kPermissionDenied,
                              "missing or wrong CSRF token (X-CSRF-Token)", "csrf"});
  }
  if (seg.size() == 1 && seg[0] == "signout" && post) {
    if (web) sessions_.Remove(web->id);
    HttpReply reply = NoContent();
    reply.headers.emplace_back(
        "Set-Cookie", std::string(kCookie) + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0");
    return reply;
  }
  // The route table: the first route whose verb and pattern match decides the method, which
  // decides the role (each domain function checks again); a malformed parameter is 400.
  for (const Route& route : kRoutes) {
    if (std::string_view(route.verb) != (post ? "POST" : "GET")) continue;
    Call call{*this, r, query, web, authorization, nullptr, 0, {}};
    auto matched = Match(route.pattern, seg, call);
    if (!matched.ok()) return ErrorReply(matched.error());
    if (!*matched) continue;
    auto p = Authorize(d_.store, authorization, route.method);
    if (!p.ok()) {
      if (bearer && p.error().code == ErrorCode::kUnauthenticated) BearerRefused(r.remote);
      return ErrorReply(p.error());
    }
    call.p = &*p;
    return route.handler(call);
  }
  return ErrorReply(
      Error{ErrorCode::kNotFound, "no such API route: " + r.method + " /api/v1" + path, "path"});
}

void HttpApi::BearerRefused(const std::string& remote) {
  bearer_limiter_.Failed(remote);
  const uint64_t n = bearer_failures_.fetch_add(1) + 1;
  if ((n & (n - 1)) == 0)  // the 1st, 2nd, 4th, 8th, …: a flood logs a few lines
    LogEvent("vsurg-http", "bearer_token_refused", {{"remote", remote}, {"total", n}});
}

// A pattern's segments are literals, `{id}` (a session id: a positive integer) or `{name}` (a
// percent-encoded name). true: matched (parameters in `call`); false: another route's; an error:
// this route's shape with a malformed parameter.
Expected<bool> HttpApi::Match(std::string_view pattern, const std::vector<std::string_view>& seg,
                              Call& call) {
  const std::vector<std::string_view> want = Segments(pattern);
  if (want.size() != seg.size()) return false;
  for (size_t i = 0; i < want.size(); ++i)
    if (want[i].front() != '{' && want[i] != seg[i]) return false;
  for (size_t i = 0; i < want.size(); ++i) {
    if (want[i] == "{id}") {
      const auto id = ParseId(seg[i]);
      if (!id) return InvalidArgument("id", "a session id is a positive integer");
      call.id = *id;
    } else if (want[i] == "{name}") {
      auto name = UrlDecode(seg[i]);
      if (!name) return InvalidArgument("name", "a malformed name");
      call.name = std::move(*name);
    }
  }
  return true;
}

}  // namespace vsurg::server::http
