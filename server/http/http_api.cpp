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
#include "server/http/http_reply.h"
#include "server/http/http_routes.h"
#include "server/http/http_views.h"
#include "server/http/web_assets.h"
#include "server/ops/metrics.h"

namespace vsurg::server::http {

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

namespace {

// A pool of fairly shared workers, or none (0 workers: the work runs on the calling thread).
std::unique_ptr<FairWorkers> MakeWorkers(int workers, int max_queued, int per_user_queued,
                                         const char* thread_name) {
  if (workers <= 0) return nullptr;
  return std::make_unique<FairWorkers>(FairWorkersOptions{.workers = workers,
                                                          .max_queued = max_queued,
                                                          .per_user_queued = per_user_queued,
                                                          .thread_name = thread_name});
}

}  // namespace

HttpApi::HttpApi(Domain& domain, const HttpApiOptions& options)
    : d_(domain),
      options_(options),
      clock_(options.clock ? *options.clock : DefaultClock()),
      reads_(MakeWorkers(options.read_workers, options.max_queued_reads,
                         options.per_user_queued_reads, "vsurg-http-read")),
      node_calls_(MakeWorkers(options.node_workers, options.max_queued_node_calls,
                              options.per_user_queued_reads, "vsurg-http-node")),
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

HttpReply HttpApi::MetricsReply() const {
  if (!options_.metrics)
    return ErrorReply(Error{ErrorCode::kNotFound, "this process keeps no metrics", ""});
  HttpReply r;
  r.content_type = "text/plain; version=0.0.4; charset=utf-8";
  r.body = options_.metrics->Render();
  r.headers.emplace_back("Cache-Control", "no-store");
  return r;
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
    {"GET", "sessions/{id}/guidance", Method::kSessionGet, &Routes::SessionGuidanceRoute},
    {"POST", "sessions/{id}/guide", Method::kSessionGuide, &Routes::SessionGuide},
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
  // The ways to sign in (the sign-in page offers the provider's when there is one), and the
  // provider's way there and back.
  if (get && seg.size() == 2 && seg[0] == "signin" && seg[1] == "methods")
    return Ok({{"token", true}, {"oidc", options_.oidc != nullptr}});
  if (get && seg.size() == 2 && seg[0] == "signin" && seg[1] == "oidc") return OidcBegin(r);
  if (get && seg.size() == 3 && seg[0] == "signin" && seg[1] == "oidc" && seg[2] == "callback")
    return OidcCallback(r, query);

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
