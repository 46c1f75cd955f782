// The dashboard's HTTP layer without a socket (server/http/http_api.h): routing, pages by role,
// sign-in, cookies and their expiry, CSRF, the sign-in rate limit, JSON encoding and escaping.
// A real SQLite store and session manager underneath, as for the gRPC services.
#include "server/http/http_api.h"
#include "server/http/request_checks.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <future>
#include <limits>
#include <nlohmann/json.hpp>

#include "server/domain/scene_catalog.h"
#include "server/ops/metrics.h"
#include "server/ops/session_metrics.h"
#include "server/session/session_manager.h"
#include "tests/support/site.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::server::http {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string Header(const HttpReply& r, const std::string& name) {
  for (const auto& [n, v] : r.headers)
    if (n == name) return v;
  return "";
}

class HttpApiTest : public test::SiteTest {
 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(OpenSite());
    domain_ = std::make_unique<Domain>(Domain{*store_, *sessions_, catalog_, backups()});
    AddUsers({{"tina", db::Role::kTrainee, "novice"},
              {"ian", db::Role::kInstructor, ""},
              {"eve", db::Role::kEvaluator, "chief"},
              {"<script>alert(1)</script>", db::Role::kTrainee, "novice"}});
    HttpApiOptions o;
    o.clock = &clock_;
    o.session_ttl_s = 3600;
    session_metrics_ = std::make_unique<ops::SessionMetrics>(*sessions_);
    metrics_.Add([this](ops::MetricsText& m) { session_metrics_->Collect(m); });
    o.metrics = &metrics_;
    api_ = std::make_unique<HttpApi>(*domain_, o);
  }
  void TearDown() override {
    api_.reset();
    session_metrics_.reset();
    domain_.reset();
    SiteTest::TearDown();
  }

  // A request's final answer (a deferred one waited for: a call that waits on the sessions, a
  // long read, an evaluation's commit).
  HttpReply Call(const std::string& method, const std::string& target, const std::string& body = "",
                 const std::string& cookie = "", const std::string& csrf = "",
                 const std::string& remote = "10.0.0.1") {
    return Finish(Raw(method, target, body, cookie, csrf, remote));
  }
  // The reply as Handle gives it (deferred or not).
  HttpReply Raw(const std::string& method, const std::string& target, const std::string& body = "",
                const std::string& cookie = "", const std::string& csrf = "",
                const std::string& remote = "10.0.0.1") {
    HttpRequest r;
    r.method = method;
    r.target = target;
    r.body = body;
    r.cookie = cookie;
    r.csrf = csrf;
    r.remote = remote;
    if (!body.empty()) r.content_type = "application/json";
    return api_->Handle(r);
  }
  struct Signed {
    std::string cookie, csrf;
  };
  Signed SignIn(const std::string& token) {
    const HttpReply r = Call("POST", "/api/v1/signin", json{{"token", token}}.dump());
    EXPECT_EQ(r.status, 200) << r.body;
    const std::string set = Header(r, "Set-Cookie");
    return {set.substr(0, set.find(';')), json::parse(r.body)["csrf"].get<std::string>()};
  }
  // A deferred reply's final answer (an evaluation waits for the store's commit).
  static HttpReply Finish(HttpReply r) {
    if (r.kind != HttpReply::Kind::kDeferred) return r;
    std::promise<HttpReply> done;
    r.deferred([&](HttpReply x) { done.set_value(std::move(x)); });
    return done.get_future().get();
  }

  ManualClock clock_{100};
  SceneCatalog catalog_;
  std::unique_ptr<Domain> domain_;
  ops::MetricsRegistry metrics_;
  std::unique_ptr<ops::SessionMetrics> session_metrics_;
  std::unique_ptr<HttpApi> api_;
};

TEST_F(HttpApiTest, SignInGivesAStrictHttpOnlyCookieThatExpiresAndSignOutForgetsIt) {
  const HttpReply r = Call("POST", "/api/v1/signin", json{{"token", tokens_["ian"]}}.dump());
  ASSERT_EQ(r.status, 200) << r.body;
  const std::string cookie = Header(r, "Set-Cookie");
  EXPECT_NE(cookie.find("HttpOnly"), std::string::npos) << cookie;
  EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos);
  EXPECT_NE(cookie.find("Max-Age=3600"), std::string::npos);
  EXPECT_NE(cookie.find("Path=/"), std::string::npos);
  EXPECT_EQ(cookie.find(tokens_["ian"]), std::string::npos) << "the API token never leaves";
  const json body = json::parse(r.body);
  EXPECT_EQ(body["user"], "ian");
  EXPECT_EQ(body["role"], "instructor");
  EXPECT_EQ(body["csrf"].get<std::string>().size(), 64u);

  const std::string jar = cookie.substr(0, cookie.find(';'));
  EXPECT_EQ(Call("GET", "/api/v1/me", "", jar).status, 200);
  clock_.Advance(3599);
  EXPECT_EQ(Call("GET", "/api/v1/me", "", jar).status, 200);
  clock_.Advance(2);  // past the expiry: no sliding renewal
  EXPECT_EQ(Call("GET", "/api/v1/me", "", jar).status, 401);

  const Signed again = SignIn(tokens_["ian"]);
  const HttpReply out = Call("POST", "/api/v1/signout", "", again.cookie, again.csrf);
  EXPECT_EQ(out.status, 204);
  EXPECT_NE(Header(out, "Set-Cookie").find("Max-Age=0"), std::string::npos);
  EXPECT_EQ(Call("GET", "/api/v1/me", "", again.cookie).status, 401);
}

TEST_F(HttpApiTest, FailedSignInsAreLimitedPerAddress) {
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(Call("POST", "/api/v1/signin", json{{"token", "vst_wrong"}}.dump()).status, 401);
  // The sixth try from that address is refused even with a valid token; another address is not.
  const HttpReply limited = Call("POST", "/api/v1/signin", json{{"token", tokens_["ian"]}}.dump());
  EXPECT_EQ(limited.status, 429);
  EXPECT_GE(std::stoi(Header(limited, "Retry-After")), 1);
  EXPECT_EQ(
      Call("POST", "/api/v1/signin", json{{"token", tokens_["ian"]}}.dump(), "", "", "10.0.0.2")
          .status,
      200);
  clock_.Advance(61);  // the failures left the window
  EXPECT_EQ(Call("POST", "/api/v1/signin", json{{"token", tokens_["ian"]}}.dump()).status, 200);
}

// Guesses through the Authorization header are counted and limited per address as sign-ins are
// (harmless at 256 bits, but nobody should get unlimited tries); a known token is unaffected, and
// another address is not limited by the guesser.
TEST_F(HttpApiTest, BearerTokenGuessesAreCountedAndLimitedPerAddress) {
  auto with = [&](const std::string& token, const std::string& remote) {
    HttpRequest r;
    r.method = "GET";
    r.target = "/api/v1/sessions";
    r.authorization = "Bearer " + token;
    r.remote = remote;
    return api_->Handle(r);
  };
  for (int i = 0; i < 20; ++i)
    EXPECT_EQ(with("guess-" + std::to_string(i), "10.0.0.66").status, 401) << i;
  EXPECT_EQ(api_->bearer_failures(), 20u);
  const HttpReply limited = with("guess-20", "10.0.0.66");
  EXPECT_EQ(limited.status, 429);
  EXPECT_FALSE(Header(limited, "Retry-After").empty());
  EXPECT_EQ(api_->bearer_failures(), 20u) << "a limited request is not even tried";
  EXPECT_EQ(with(tokens_["ian"], "10.0.0.7").status, 200);
  EXPECT_EQ(with("guess-21", "10.0.0.7").status, 401);
  clock_.Advance(61);
  EXPECT_EQ(with(tokens_["ian"], "10.0.0.66").status, 200);
}

// One user signing in again and again never signs anyone else out (the web-session table is
// bounded per user), and signing out is counted, so that the server ends that web session's
// event streams (HttpServerTest checks the streams themselves).
TEST_F(HttpApiTest, ManySignInsOfOneUserLeaveOthersSignedIn) {
  const Signed ian = SignIn(tokens_["ian"]);
  for (int i = 0; i < 4100; ++i) SignIn(tokens_["tina"]);
  EXPECT_EQ(Call("GET", "/api/v1/sessions", "", ian.cookie).status, 200);
  const uint64_t before = api_->signouts();
  EXPECT_EQ(Call("POST", "/api/v1/signout", "", ian.cookie, ian.csrf).status, 204);
  EXPECT_GT(api_->signouts(), before);
  EXPECT_EQ(Call("GET", "/api/v1/sessions", "", ian.cookie).status, 401);
}

TEST_F(HttpApiTest, StateChangingRequestsNeedTheCsrfTokenOfTheirSession) {
  const Signed admin = SignIn(admin_);
  const std::string user = json{{"name", "nina"}, {"role", "trainee"}, {"group", "g"}}.dump();
  EXPECT_EQ(Call("POST", "/api/v1/users", user, admin.cookie).status, 403);
  EXPECT_EQ(Call("POST", "/api/v1/users", user, admin.cookie, std::string(64, '0')).status, 403);
  const Signed other = SignIn(tokens_["ian"]);  // another session's token is not this one's
  EXPECT_EQ(Call("POST", "/api/v1/users", user, admin.cookie, other.csrf).status, 403);
  EXPECT_FALSE(store_->Authenticate(tokens_["ian"]).value().name.empty());
  EXPECT_EQ(store_->ListUsers().value().size(), 5u) << "nothing was written";
  EXPECT_EQ(Call("POST", "/api/v1/users", user, admin.cookie, admin.csrf).status, 201);
  // A form post (not JSON) is refused even with the token.
  HttpRequest form;
  form.method = "POST";
  form.target = "/api/v1/users";
  form.cookie = admin.cookie;
  form.csrf = admin.csrf;
  form.content_type = "application/x-www-form-urlencoded";
  form.body = "name=x&role=admin";
  EXPECT_EQ(api_->Handle(form).status, 400);
  // Scripts with a bearer header (never sent by a browser on its own) need no CSRF token.
  HttpRequest bearer;
  bearer.method = "POST";
  bearer.target = "/api/v1/users";
  bearer.authorization = "Bearer " + admin_;
  bearer.content_type = "application/json";
  bearer.body = json{{"name", "omar"}, {"role", "trainee"}, {"group", "g"}}.dump();
  EXPECT_EQ(api_->Handle(bearer).status, 201);
}

TEST_F(HttpApiTest, EveryPageAndRouteChecksTheRole) {
  // Anonymous: pages send to sign-in, the API says 401.
  const HttpReply anon = Call("GET", "/live");
  EXPECT_EQ(anon.status, 303);
  EXPECT_EQ(Header(anon, "Location"), "/signin?next=live");
  EXPECT_EQ(Call("GET", "/api/v1/users").status, 401);
  EXPECT_EQ(Call("GET", "/signin").status, 200);

  const Signed tina = SignIn(tokens_["tina"]);
  for (const char* page : {"/live", "/evaluate", "/reports", "/admin"})
    EXPECT_EQ(Call("GET", page, "", tina.cookie).status, 403) << page;
  // A session's page and the records are shells for anyone signed in: what they show comes from
  // the API, which keeps a trainee to her own sessions (SessionsAreRecords below).
  for (const char* page : {"/mine", "/session/1", "/records"})
    EXPECT_EQ(Call("GET", page, "", tina.cookie).status, 200) << page;
  for (const char* route : {"/api/v1/users", "/api/v1/live/events", "/api/v1/export",
                            "/api/v1/reports?kind=trainee&subject=tina", "/api/v1/evaluations/mine",
                            "/api/v1/training-effect"})
    EXPECT_EQ(Call("GET", route, "", tina.cookie).status, 403) << route;
  EXPECT_EQ(
      Call("POST", "/api/v1/backup", json{{"name", "b.db"}}.dump(), tina.cookie, tina.csrf).status,
      403);
  EXPECT_EQ(Call("GET", "/", "", tina.cookie).status, 303);

  const Signed ian = SignIn(tokens_["ian"]);
  EXPECT_EQ(Call("GET", "/live", "", ian.cookie).status, 200);
  EXPECT_EQ(Call("GET", "/reports", "", ian.cookie).status, 200);
  EXPECT_EQ(Call("GET", "/admin", "", ian.cookie).status, 403);
  EXPECT_EQ(Call("GET", "/evaluate", "", ian.cookie).status, 403);
  const HttpReply live = Call("GET", "/api/v1/live/events", "", ian.cookie);
  EXPECT_EQ(live.status, 200);
  EXPECT_EQ(live.kind, HttpReply::Kind::kEvents);

  const Signed admin = SignIn(admin_);
  for (const char* page : {"/live", "/evaluate", "/reports", "/admin"})
    EXPECT_EQ(Call("GET", page, "", admin.cookie).status, 200) << page;
  const HttpReply shell = Call("GET", "/admin", "", admin.cookie);
  EXPECT_NE(shell.body.find("data-page=\"admin\""), std::string::npos);
  EXPECT_EQ(shell.content_type, "text/html; charset=utf-8");
}

TEST_F(HttpApiTest, SessionsAreRecordsEveryReaderMayOpenAndATraineeOnlyHerOwn) {
  AddUsers({{"tom", db::Role::kTrainee, "novice"}});
  // Two ended trials (tina's with a record and a rating with a comment, tom's without) and a live
  // one of tina's.
  const int64_t mine = store_->CreateSession("tina", "arm-torsion").value().id;
  ASSERT_TRUE(store_->SetSessionState(mine, SessionState::kRunning, db::NowUs()).ok());
  scoring::TrialMetrics m;
  m.score = 7.5;
  ASSERT_TRUE(store_
                  ->EndSession(mine, SessionState::kEnded, db::NowUs(), "done", m, {},
                               R"({"series":{"time_s":[0,0.5],"force_n":[0,1.25]}})")
                  .ok());
  const int64_t his = store_->CreateSession("tom", "arm-torsion").value().id;
  ASSERT_TRUE(store_->EndSession(his, SessionState::kEnded, db::NowUs(), "done", m).ok());
  const int64_t live = store_->CreateSession("tina", "arm-torsion").value().id;
  const Signed eve = SignIn(tokens_["eve"]);
  const std::string rating = json{{"idempotency_key", "k1"},
                                  {"subject_kind", "session"},
                                  {"subject", std::to_string(mine)},
                                  {"moment_min", 30},
                                  {"comment", "Steady; release more gently."},
                                  {"scores", {7, 7, 7, 7, 7, 7, 7, 7, 7}}}
                                 .dump();
  ASSERT_EQ(Finish(Call("POST", "/api/v1/evaluations", rating, eve.cookie, eve.csrf)).status, 201);

  // The evaluator opens the session's page and reads its record (she scores beside it).
  EXPECT_EQ(Call("GET", "/session/" + std::to_string(mine), "", eve.cookie).status, 200);
  const HttpReply trace =
      Call("GET", "/api/v1/sessions/" + std::to_string(mine) + "/trace", "", eve.cookie);
  ASSERT_EQ(trace.status, 200) << trace.body;
  EXPECT_EQ(json::parse(trace.body)["series"]["force_n"][1], 1.25);
  EXPECT_EQ(
      Call("GET", "/api/v1/sessions/" + std::to_string(his) + "/trace", "", eve.cookie).status,
      404);  // never driven: no record, said as such
  const json feedback = json::parse(
      Call("GET", "/api/v1/sessions/" + std::to_string(mine) + "/feedback", "", eve.cookie).body);
  ASSERT_EQ(feedback["ratings"].size(), 1u);
  EXPECT_EQ(feedback["ratings"][0]["comment"], "Steady; release more gently.");
  EXPECT_EQ(feedback["ratings"][0]["moment_min"], 30);
  EXPECT_EQ(feedback["ratings"][0]["evaluator"], "eve");
  // Her own submissions list the moment and the comment.
  const json own = json::parse(Call("GET", "/api/v1/evaluations/mine", "", eve.cookie).body);
  EXPECT_EQ(own["submitted"][0]["comment"], "Steady; release more gently.");

  // The records: ended sessions only, newest first, filtered and paged.
  const Signed ian = SignIn(tokens_["ian"]);
  json page = json::parse(Call("GET", "/api/v1/records", "", ian.cookie).body);
  EXPECT_EQ(page["total"], 2);
  EXPECT_EQ(page["sessions"][0]["id"], his);
  EXPECT_EQ(page["sessions"][1]["has_record"], true);
  EXPECT_EQ(page["sessions"][1]["score"], 7.5);
  page = json::parse(Call("GET", "/api/v1/records?trainee=tina&per_page=1", "", ian.cookie).body);
  EXPECT_EQ(page["total"], 1);
  EXPECT_EQ(page["sessions"][0]["id"], mine);
  for (const char* bad : {"?min_score=11", "?per_page=0", "?page=x", "?from=yesterday"})
    EXPECT_EQ(Call("GET", std::string("/api/v1/records") + bad, "", ian.cookie).status, 400) << bad;

  // tina reads her own session's record and feedback (without the rater's name), never tom's.
  const Signed tina = SignIn(tokens_["tina"]);
  const json hers = json::parse(
      Call("GET", "/api/v1/sessions/" + std::to_string(mine) + "/feedback", "", tina.cookie).body);
  EXPECT_EQ(hers["ratings"][0]["comment"], "Steady; release more gently.");
  EXPECT_FALSE(hers["ratings"][0].contains("evaluator"));
  for (const char* what : {"/trace", "/feedback", ""})
    EXPECT_EQ(Call("GET", "/api/v1/sessions/" + std::to_string(his) + what, "", tina.cookie).status,
              403)
        << what;
  page = json::parse(Call("GET", "/api/v1/records", "", tina.cookie).body);
  EXPECT_EQ(page["total"], 1);  // hers only
  EXPECT_EQ(Call("GET", "/api/v1/records?trainee=tom", "", tina.cookie).status, 403);
  // A live session of hers that the manager does not run (no record yet): not found, not a crash.
  EXPECT_EQ(
      Call("GET", "/api/v1/sessions/" + std::to_string(live) + "/trace", "", tina.cookie).status,
      404);

  // The rated subjects, for the reports' pickers.
  const json subjects =
      json::parse(Call("GET", "/api/v1/subjects?kind=session", "", ian.cookie).body);
  EXPECT_EQ(subjects["subjects"], json::array({std::to_string(mine)}));
  EXPECT_EQ(Call("GET", "/api/v1/subjects?kind=planet", "", ian.cookie).status, 400);
  EXPECT_EQ(Call("GET", "/api/v1/subjects?kind=model", "", tina.cookie).status, 403);
}

TEST_F(HttpApiTest, RevokingTokensOrDisablingEndsTheWebSessionAtTheNextRequest) {
  const Signed ian = SignIn(tokens_["ian"]);
  const Signed admin = SignIn(admin_);
  EXPECT_EQ(Call("GET", "/api/v1/me", "", ian.cookie).status, 200);
  EXPECT_EQ(Call("POST", "/api/v1/users/ian/revoke", "", admin.cookie, admin.csrf).status, 204);
  EXPECT_EQ(Call("GET", "/api/v1/me", "", ian.cookie).status, 401);
  EXPECT_EQ(Call("GET", "/live", "", ian.cookie).status, 303);

  const Signed eve = SignIn(tokens_["eve"]);
  EXPECT_EQ(Call("POST", "/api/v1/users/eve/disabled", json{{"disabled", true}}.dump(),
                 admin.cookie, admin.csrf)
                .status,
            204);
  EXPECT_EQ(Call("GET", "/api/v1/evaluations/mine", "", eve.cookie).status, 401);
}

TEST_F(HttpApiTest, UnknownRoutesAndBadInputGetAClearStatusAndWriteNothing) {
  const Signed admin = SignIn(admin_);
  const HttpReply missing = Call("GET", "/api/v1/nothing/here", "", admin.cookie);
  EXPECT_EQ(missing.status, 404);
  EXPECT_NE(json::parse(missing.body)["error"].get<std::string>().find("no such API route"),
            std::string::npos);
  EXPECT_EQ(Call("GET", "/no-such-page", "", admin.cookie).status, 404);
  EXPECT_EQ(Call("GET", "/session/abc", "", admin.cookie).status, 404);
  EXPECT_EQ(Call("DELETE", "/api/v1/users", "", admin.cookie, admin.csrf).status, 400);
  EXPECT_EQ(Call("GET", "/api/v1/sessions/12x", "", admin.cookie).status, 400);
  EXPECT_EQ(Call("GET", "/api/v1/sessions/999", "", admin.cookie).status, 404);
  EXPECT_EQ(Call("GET", "/api/v1/reports?kind=%zz", "", admin.cookie).status, 400);
  for (const char* body : {"{", "[1,2]", "\"text\"", "{\"name\": 5}",
                           "{\"name\": \"x\", "
                           "\"role\": \"king\"}"}) {
    const HttpReply r = Call("POST", "/api/v1/users", body, admin.cookie, admin.csrf);
    EXPECT_EQ(r.status, 400) << body << " " << r.body;
    EXPECT_TRUE(json::parse(r.body).contains("error"));
  }
  EXPECT_EQ(store_->ListUsers().value().size(), 5u);
  EXPECT_EQ(Call("GET", "/api/v1/export?format=pdf", "", admin.cookie).status, 400);
  EXPECT_EQ(Call("GET", "/api/v1/export?from=yesterday", "", admin.cookie).status, 400);
  EXPECT_EQ(
      Call("POST", "/api/v1/backup", json{{"name", "../x.db"}}.dump(), admin.cookie, admin.csrf)
          .status,
      400);
}

TEST_F(HttpApiTest, AnEvaluatorSubmitsOnceAndARetryIsTheSameSubmission) {
  const Signed eve = SignIn(tokens_["eve"]);
  json body = {{"idempotency_key", "web:1"},
               {"subject_kind", "model"},
               {"subject", "coil"},
               {"scores", {7, 7, 7, 7, 7, 7, 7, 7, 7}}};
  const HttpReply first =
      Finish(Call("POST", "/api/v1/evaluations", body.dump(), eve.cookie, eve.csrf));
  EXPECT_EQ(first.status, 201) << first.body;
  const HttpReply retry =
      Finish(Call("POST", "/api/v1/evaluations", body.dump(), eve.cookie, eve.csrf));
  EXPECT_EQ(retry.status, 200);
  EXPECT_TRUE(json::parse(retry.body)["duplicate"].get<bool>());
  EXPECT_EQ(json::parse(retry.body)["submission_id"], json::parse(first.body)["submission_id"]);
  body["scores"][0] = 11;  // out of 0..10: refused on the server too
  body["idempotency_key"] = "web:2";
  body["subject"] = "fem";
  EXPECT_EQ(Finish(Call("POST", "/api/v1/evaluations", body.dump(), eve.cookie, eve.csrf)).status,
            400);
  const json mine = json::parse(Call("GET", "/api/v1/evaluations/mine", "", eve.cookie).body);
  ASSERT_EQ(mine["submitted"].size(), 1u);
  EXPECT_EQ(mine["submitted"][0]["subject"], "coil");
  for (const auto& m : mine["models"]) EXPECT_NE(m, "coil") << "scored models leave the queue";
  const HttpReply report =
      Call("GET", "/api/v1/reports?kind=model&subject=coil", "", SignIn(admin_).cookie);
  ASSERT_EQ(report.status, 200) << report.body;
  EXPECT_EQ(json::parse(report.body)["raters"], 1);
}

TEST_F(HttpApiTest, JsonIsEscapedAndNeverCarriesNaN) {
  const Signed admin = SignIn(admin_);
  const json users = json::parse(Call("GET", "/api/v1/users", "", admin.cookie).body);
  bool found = false;
  for (const auto& u : users["users"]) found |= u["name"] == "<script>alert(1)</script>";
  EXPECT_TRUE(found) << "the name round-trips as data";

  SessionTelemetry t;
  t.id = 7;
  t.trainee = "a\"b\\c\n<script>";
  t.scene = "arm-torsion";
  t.sim.force = geometry::Vec3(std::numeric_limits<double>::quiet_NaN(), 1, 2);
  t.sim.twist = std::numeric_limits<double>::infinity();
  t.rtt_us = 120;
  t.has_surface = true;
  t.surface_indices = {3};
  t.surface_positions = {geometry::Vec3(0.01, 0.02, 0.0305)};
  const std::string text = HttpApi::TelemetryJson(t, true);
  EXPECT_EQ(text.find("NaN"), std::string::npos);
  EXPECT_EQ(text.find('\n'), std::string::npos) << "one line per server-sent event";
  const json j = json::parse(text);
  EXPECT_EQ(j["trainee"], t.trainee);
  EXPECT_EQ(j["force_vector_n"][0], 0.0);
  EXPECT_EQ(j["force_n"], 0.0);  // |(NaN, 1, 2)| is NaN too
  EXPECT_EQ(j["twist_deg"], 0.0);
  EXPECT_EQ(j["rtt_us"], 120.0);
  // Every number's name carries its unit (or is a count, a flag or the score).
  for (const char* name : {"time_s", "force_n", "twist_deg", "torque_nm", "depth_mm", "rtt_us",
                           "loss_ratio", "haptic_rate_hz", "peak_force_n", "score", "samples",
                           "clock_jumps", "overload_events", "packets", "contact", "grasping"})
    EXPECT_TRUE(j.contains(name)) << name;
  for (const char* old : {"time", "force", "torque", "loss", "rate_hz"})
    EXPECT_FALSE(j.contains(old)) << old;
  EXPECT_DOUBLE_EQ(j["surface"]["positions_mm"][2].get<double>(), 30.5);
  EXPECT_FALSE(json::parse(HttpApi::TelemetryJson(t, false)).contains("surface"));
}

TEST_F(HttpApiTest, ErrorCodesMapToHttpStatusesOnce) {
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kInvalidArgument), 400);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kParseError), 400);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kUnauthenticated), 401);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kPermissionDenied), 403);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kNotFound), 404);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kAlreadyExists), 409);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kResourceExhausted), 429);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kUnavailable), 503);
  EXPECT_EQ(HttpApi::StatusFor(ErrorCode::kIoError), 500);
}

// RFC 9112 §6.3: a body's length must be unambiguous; and the Host must be ours.
TEST(RequestChecksTest, OnlyALoneChunkedTransferEncodingAndKnownHostsPass) {
  EXPECT_EQ(FramingProblem({}, 0), "");
  EXPECT_EQ(FramingProblem({}, 1), "");
  EXPECT_EQ(FramingProblem({"chunked"}, 0), "");
  EXPECT_EQ(FramingProblem({" Chunked "}, 0), "");
  for (const char* te : {"chunked, identity", "identity", "xchunked", "gzip, chunked", "",
                         "chunked,", "chunked;q=1"})
    EXPECT_NE(FramingProblem({te}, 0), "") << te;
  EXPECT_NE(FramingProblem({"chunked"}, 1), "");
  EXPECT_NE(FramingProblem({"identity"}, 1), "");
  EXPECT_NE(FramingProblem({"chunked", "chunked"}, 0), "");
  const std::vector<std::string> names = {"dashboard.example.org"};
  for (const char* ok :
       {"127.0.0.1", "127.0.0.1:8443", "10.1.2.3", "[::1]", "[::1]:80", "localhost",
        "LOCALHOST:8080", "dashboard.example.org", "Dashboard.Example.org:443"})
    EXPECT_TRUE(HostAllowed(ok, names)) << ok;
  for (const char* bad :
       {"", "evil.example", "evil.example:80", "dashboard.example.org.evil",
        "127.0.0.1:", "127.0.0.1:x", "[::1", "[::1]x", "[nothost]", ":80", "1.2.3.4.5"})
    EXPECT_FALSE(HostAllowed(bad, names)) << bad;
}

TEST(HttpHelpersTest, QueriesCookiesAndSecretsParseStrictly) {
  EXPECT_EQ(UrlDecode("a%20b+c").value(), "a b c");
  EXPECT_FALSE(UrlDecode("%4").has_value());
  EXPECT_FALSE(UrlDecode("%zz").has_value());
  const auto q = ParseQuery("subject=a&subject=b&kind=session&&x=").value();
  EXPECT_EQ(q.count("subject"), 2u);
  EXPECT_EQ(q.find("kind")->second, "session");
  EXPECT_EQ(q.find("x")->second, "");
  EXPECT_FALSE(ParseQuery("a=%").has_value());
  EXPECT_EQ(CookieValue("a=1; vsurg_session=abc ; b=2", "vsurg_session").value(), "abc");
  EXPECT_FALSE(CookieValue("xvsurg_session=abc", "vsurg_session").has_value());
  EXPECT_FALSE(CookieValue("", "vsurg_session").has_value());
  EXPECT_TRUE(SameSecret("abc", "abc"));
  EXPECT_FALSE(SameSecret("abc", "abd"));
  EXPECT_FALSE(SameSecret("abc", "abcd"));
  EXPECT_FALSE(SameSecret("", "a"));
  EXPECT_NE(RandomHex32(), RandomHex32());
}

TEST(WebSessionsTest, AreBoundedPerUserAndForgetThatUsersOldestFirst) {
  ManualClock clock(0);
  WebSessions s(clock, 100, 3);
  const WebSession instructor = s.Create("t-ivo", "ivo");
  const WebSession a = s.Create("t1", "tina");
  clock.Advance(1);
  const WebSession b = s.Create("t2", "tina");
  clock.Advance(1);
  s.Create("t3", "tina");
  s.Create("t4", "tina");
  EXPECT_EQ(s.size_of("tina"), 3u);
  EXPECT_FALSE(s.Find(a.id).has_value());
  EXPECT_EQ(s.Find(b.id)->token, "t2");
  // One user signing in 4,100 times signs out only their own oldest sessions, never another's.
  for (int i = 0; i < 4100; ++i) s.Create("t", "tina");
  EXPECT_EQ(s.size_of("tina"), 3u);
  EXPECT_EQ(s.size(), 4u);
  ASSERT_TRUE(s.Find(instructor.id).has_value());
  EXPECT_EQ(s.Find(instructor.id)->user, "ivo");
  const uint64_t removed = s.removals();
  s.Remove(instructor.id);
  EXPECT_EQ(s.removals(), removed + 1);  // a sign-out is counted: its streams end
  clock.Advance(100);
  EXPECT_FALSE(s.Find(b.id).has_value());
}

// The training programme's routes: the instructor builds a course and a cohort from the page's
// calls (cookie and CSRF), a bad spec names its field, the grid and the curve answer, a trainee
// is refused the grid, and the progress export is a download produced on the export worker.
// The Prometheus text format: HELP and TYPE before the samples, label values escaped, NaN and
// infinities spelled as Prometheus reads them, histogram buckets cumulative up to +Inf.
TEST(MetricsTextTest, WritesFamiliesLabelsAndCumulativeHistograms) {
  ops::MetricsText t;
  t.Family("vsurg_x_total", "counter", "A count.\nOn two lines.");
  t.Sample("vsurg_x_total", {{"who", "a\"b\\c\nd"}}, 3);
  t.Sample("vsurg_x_total", {}, std::nan(""));
  t.Histogram("vsurg_rtt_seconds", "Round trips.", {{"node", "n1"}}, {0.5, 2}, {0.25, 0.5, 1, 8});
  EXPECT_EQ(t.str(),
            "# HELP vsurg_x_total A count. On two lines.\n"
            "# TYPE vsurg_x_total counter\n"
            "vsurg_x_total{who=\"a\\\"b\\\\c\\nd\"} 3\n"
            "vsurg_x_total NaN\n"
            "# HELP vsurg_rtt_seconds Round trips.\n"
            "# TYPE vsurg_rtt_seconds histogram\n"
            "vsurg_rtt_seconds_bucket{node=\"n1\",le=\"0.5\"} 2\n"
            "vsurg_rtt_seconds_bucket{node=\"n1\",le=\"2\"} 3\n"
            "vsurg_rtt_seconds_bucket{node=\"n1\",le=\"+Inf\"} 4\n"
            "vsurg_rtt_seconds_sum{node=\"n1\"} 9.75\n"
            "vsurg_rtt_seconds_count{node=\"n1\"} 4\n");
}

// Counts kept as they came give the same text as the observations themselves.
TEST(MetricsTextTest, HistogramCountsMatchTheHistogramOfTheSameObservations) {
  ops::MetricsText a, b;
  a.Histogram("vsurg_rtt_seconds", "Round trips.", {{"node", "n1"}}, {0.5, 2}, {0.25, 0.5, 1, 8});
  b.HistogramCounts("vsurg_rtt_seconds", "Round trips.", {{"node", "n1"}}, {0.5, 2}, {2, 1, 1},
                    9.75);
  EXPECT_EQ(a.str(), b.str());
}

// A simulation node's listener (metrics_only): the scrape, and nothing else (no page, no route
// that would create a session behind the control plane's back). And Prometheus' token
// (metrics_token): the scrape, and nothing else.
TEST_F(HttpApiTest, AMetricsOnlyListenerServesTheScrapeAndNothingElse) {
  HttpApiOptions o;
  o.clock = &clock_;
  o.metrics = &metrics_;
  o.metrics_only = true;
  HttpApi node(*domain_, o);
  const auto get = [&](const std::string& target) {
    HttpRequest r;
    r.method = "GET";
    r.target = target;
    r.authorization = "Bearer " + admin_;
    r.remote = "10.0.0.9";
    return node.Handle(r);
  };
  EXPECT_EQ(get("/api/v1/metrics").status, 200);
  for (const char* target : {"/api/v1/sessions", "/live", "/", "/static/app.js", "/signin"})
    EXPECT_EQ(get(target).status, 404) << target;
  HttpRequest create;
  create.method = "POST";
  create.target = "/api/v1/sessions";
  create.authorization = "Bearer " + admin_;
  create.body = R"({"scene": "arm-torsion"})";
  EXPECT_EQ(node.Handle(create).status, 404);
  // Prometheus' own token reads the scrape and is unknown everywhere else.
  o.metrics_only = false;
  o.metrics_token = "prometheus-token-0123456789";
  HttpApi site(*domain_, o);
  const auto as = [&](const std::string& token, const std::string& target) {
    HttpRequest r;
    r.method = "GET";
    r.target = target;
    r.authorization = "Bearer " + token;
    r.remote = "10.0.0.10";
    return site.Handle(r).status;
  };
  EXPECT_EQ(as("prometheus-token-0123456789", "/api/v1/metrics"), 200);
  EXPECT_EQ(as("prometheus-token-0123456789", "/api/v1/sessions"), 401);
  EXPECT_EQ(as("prometheus-token-012345678X", "/api/v1/metrics"), 401);
  EXPECT_EQ(as(tokens_["tina"], "/api/v1/metrics"), 403);
}

// GET /api/v1/metrics: an administrator's bearer token reads the live sessions by state as the
// sampler last saw them; anyone else is refused.
TEST_F(HttpApiTest, TheMetricsAreForAnAdministratorAndFollowTheSessions) {
  const auto scrape = [&](const std::string& token) {
    HttpRequest r;
    r.method = "GET";
    r.target = "/api/v1/metrics";
    r.authorization = "Bearer " + token;
    r.remote = "10.0.0.9";
    return api_->Handle(r);
  };
  EXPECT_EQ(scrape(tokens_["tina"]).status, 403);
  EXPECT_EQ(scrape(tokens_["ian"]).status, 403);
  HttpReply r = scrape(admin_);
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.content_type, "text/plain; version=0.0.4; charset=utf-8");
  EXPECT_NE(r.body.find("vsurg_sessions_live{state=\"created\"} 0\n"), std::string::npos) << r.body;
  auto s = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(s.ok());
  EXPECT_TRUE(test::Eventually(20, [&] {
    return scrape(admin_).body.find("vsurg_sessions_live{state=\"created\"} 1\n") !=
           std::string::npos;
  }));
  EXPECT_NE(scrape(admin_).body.find("vsurg_station_rtt_seconds_count 0\n"), std::string::npos);
  ASSERT_TRUE(sessions_->Stop(static_cast<uint64_t>(s->record.id), "done").ok());
  EXPECT_TRUE(test::Eventually(20, [&] {
    return scrape(admin_).body.find("vsurg_sessions_live{state=\"created\"} 0\n") !=
           std::string::npos;
  }));
}

TEST_F(HttpApiTest, TheTrainingRoutesBuildACourseAndShowItsGrid) {
  const Signed ian = SignIn(tokens_["ian"]);
  const json spec = {{"targets", json::array({{{"metric", "peak_force_n"}, {"value", 2.5}}})},
                     {"consecutive", 1},
                     {"task", {{"target_depth_m", 0.004}, {"force_limit_n", 1.5}}}};
  json body = {
      {"name", "Basics"},
      {"exercises",
       json::array({{{"title", "Palpate"}, {"scene", "sphere-palpation-256"}, {"spec", spec}}})}};
  HttpReply r = Call("POST", "/api/v1/training/courses", body.dump(), ian.cookie, "");
  EXPECT_EQ(r.status, 403) << r.body;  // no CSRF token
  json bad = body;
  bad["exercises"][0]["spec"]["targets"][0]["metric"] = "speed";
  r = Call("POST", "/api/v1/training/courses", bad.dump(), ian.cookie, ian.csrf);
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(json::parse(r.body)["field"], "exercises[0].spec.targets[0]");
  bad = body;
  bad["exercises"][0]["spec"]["task"] = {{"target_deg", 45}};  // a twist's, on a press scene
  r = Call("POST", "/api/v1/training/courses", bad.dump(), ian.cookie, ian.csrf);
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(json::parse(r.body)["field"], "exercises[0].spec.task.target_depth_m");
  r = Call("POST", "/api/v1/training/courses", body.dump(), ian.cookie, ian.csrf);
  ASSERT_EQ(r.status, 201) << r.body;
  const int64_t course = json::parse(r.body)["course"]["id"];
  // The task as the trainee reads it: the exercise's depth and limit, the scene's hold.
  const json task = json::parse(r.body)["course"]["exercises"][0]["task"];
  EXPECT_EQ(task["kind"], "press");
  EXPECT_NEAR(task["target"].get<double>(), 4.0, 1e-9);
  EXPECT_EQ(task["unit"], "mm");
  EXPECT_NEAR(task["force_limit_n"].get<double>(), 1.5, 1e-12);
  EXPECT_NEAR(task["hold_s"].get<double>(), 2.0, 1e-12);
  r = Call("POST", "/api/v1/training/cohorts",
           json{{"name", "Residents"}, {"members", {"tina"}}}.dump(), ian.cookie, ian.csrf);
  ASSERT_EQ(r.status, 201) << r.body;
  const int64_t cohort = json::parse(r.body)["cohort"]["id"];
  r = Call("POST", "/api/v1/training/enrolments",
           json{{"course", course}, {"cohort", cohort}, {"ends", "yesterday"}}.dump(), ian.cookie,
           ian.csrf);
  EXPECT_EQ(r.status, 400);  // a date that is not one
  r = Call("POST", "/api/v1/training/enrolments",
           json{{"course", course}, {"cohort", cohort}}.dump(), ian.cookie, ian.csrf);
  ASSERT_EQ(r.status, 201) << r.body;
  const std::string grid = "/api/v1/training/cohorts/" + std::to_string(cohort) +
                           "/grid?course=" + std::to_string(course);
  r = Raw("GET", grid, "", ian.cookie);
  EXPECT_EQ(r.kind, HttpReply::Kind::kDeferred);  // computed on a read worker
  r = Finish(std::move(r));
  ASSERT_EQ(r.status, 200) << r.body;
  const json g = json::parse(r.body);
  ASSERT_EQ(g["trainees"].size(), 1u);
  EXPECT_EQ(g["trainees"][0]["exercises"][0]["state"], "not_started");
  const Signed tina = SignIn(tokens_["tina"]);
  EXPECT_EQ(Finish(Call("GET", grid, "", tina.cookie)).status, 403);
  r = Call("GET", "/api/v1/training/mine", "", tina.cookie);
  ASSERT_EQ(r.status, 200);
  EXPECT_EQ(json::parse(r.body)["courses"][0]["progress"]["next_exercise"],
            g["course"]["exercises"][0]["id"]);
  EXPECT_EQ(Call("GET", "/api/v1/training/mine?trainee=eve", "", tina.cookie).status, 403);
  // The export: refused as a reply, produced as a download.
  EXPECT_EQ(Call("GET", "/api/v1/training/export?course=1&format=pdf", "", ian.cookie).status, 400);
  EXPECT_EQ(Call("GET", "/api/v1/training/export?course=1", "", ian.cookie).status, 400);
  r = Call("GET", "/api/v1/training/export?course=1&cohort=" + std::to_string(cohort), "",
           ian.cookie);
  ASSERT_EQ(r.kind, HttpReply::Kind::kExport);
  ASSERT_TRUE(r.produce);
  std::string csv;
  ASSERT_TRUE(r.produce([&](std::string_view chunk) {
                 csv += chunk;
                 return true;
               }).ok());
  EXPECT_NE(csv.find("Basics,1,Palpate,sphere-palpation-256,tina,not_started,0"), std::string::npos)
      << csv;
  // A large cohort's grid is read a page of trainees at a time; a page too large is refused.
  r = Finish(Call("GET", grid + "&limit=1&offset=0", "", ian.cookie));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(json::parse(r.body)["total_trainees"], 1);
  EXPECT_EQ(json::parse(r.body)["limit"], 1);
  r = Finish(Call("GET", grid + "&offset=5", "", ian.cookie));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_TRUE(json::parse(r.body)["trainees"].empty());
  EXPECT_EQ(Finish(Call("GET", grid + "&limit=251", "", ian.cookie)).status, 400);
  EXPECT_EQ(Finish(Call("GET", grid + "&limit=-1", "", ian.cookie)).status, 400);
}

// Reading the record of a session that has none (it ended without being driven) must not break
// the next reads of the records that exist: each answers with its own record, every time, for
// every reader.
TEST_F(HttpApiTest, ARecordThatIsNotThereLeavesEveryOtherRecordReadable) {
  const int64_t recorded = store_->CreateSession("tina", "arm-torsion").value().id;
  ASSERT_TRUE(store_->SetSessionState(recorded, SessionState::kRunning, db::NowUs()).ok());
  scoring::TrialMetrics m;
  m.score = 6;
  const std::string record = R"({"series":{"time_s":[0,0.5],"force_n":[0,1.25]}})";
  ASSERT_TRUE(
      store_->EndSession(recorded, SessionState::kEnded, db::NowUs(), "done", m, {}, record).ok());
  const int64_t undriven = store_->CreateSession("tina", "arm-torsion").value().id;
  ASSERT_TRUE(store_->SetSessionState(undriven, SessionState::kEnded, db::NowUs(), "stopped").ok());
  const Signed ian = SignIn(tokens_["ian"]), tina = SignIn(tokens_["tina"]);
  const auto trace = [&](int64_t id, const Signed& who) {
    return Finish(Call("GET", "/api/v1/sessions/" + std::to_string(id) + "/trace", "", who.cookie));
  };
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(trace(undriven, i % 2 ? ian : tina).status, 404) << i;
    const HttpReply r = trace(recorded, i % 2 ? tina : ian);
    EXPECT_EQ(r.status, 200) << i << ": " << r.body;
    EXPECT_EQ(r.body, record) << i;
  }
}

}  // namespace
}  // namespace vsurg::server::http
