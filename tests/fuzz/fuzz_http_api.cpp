// libFuzzer target: the dashboard's HTTP layer (server/http/http_api.h) as any client on the
// network can reach it, over a real store in a temporary folder. Input: a first byte choosing
// the caller (anonymous, a cookie that is not a session, an administrator's or a trainee's bearer
// token), then newline-separated method, target, content type and body.
// Properties: a known status, never 500; an error is a JSON object naming it; an anonymous caller
// reaches nothing but the sign-in route and public pages; nobody anonymous writes anything.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "server/domain/scene_catalog.h"
#include "server/http/http_api.h"
#include "server/session/session_manager.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

using namespace vsurg;
using namespace vsurg::server;

struct World {
  std::filesystem::path dir;
  std::unique_ptr<db::Store> store;
  std::unique_ptr<SessionManager> sessions;
  SceneCatalog scenes;
  std::unique_ptr<Domain> domain;
  std::unique_ptr<http::HttpApi> api;
  std::string admin, trainee;
  World() {
    dir =
        std::filesystem::temp_directory_path() / ("vsurg_fuzz_http_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    store = db::Store::Open({.path = (dir / "vsurg.db").string()}).value();
    admin = store->InitAdmin("root").value();
    (void)store->CreateUser("tina", db::Role::kTrainee, "g");
    trainee = store->IssueToken("tina", "fuzz").value();
    sessions = SessionManager::Open(*store, nullptr, SessionManagerOptions{}).value();
    domain = std::make_unique<Domain>(Domain{*store, *sessions, scenes, (dir / "b").string()});
    api = std::make_unique<http::HttpApi>(*domain, http::HttpApiOptions{});
  }
  ~World() {
    api.reset();
    domain.reset();
    sessions.reset();
    store.reset();
    std::filesystem::remove_all(dir);
  }
};

std::string Next(std::string_view& in) {
  const size_t nl = in.find('\n');
  std::string out(in.substr(0, nl));
  in = nl == std::string_view::npos ? std::string_view() : in.substr(nl + 1);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static World w;
  if (size < 1) return 0;
  std::string_view in(reinterpret_cast<const char*>(data) + 1, size - 1);
  http::HttpRequest r;
  r.method = Next(in);
  r.target = Next(in);
  r.content_type = Next(in);
  r.body = std::string(in);
  r.remote = "10.9.8.7";
  const int who = data[0] % 4;
  if (who == 1) r.cookie = "vsurg_session=" + r.method;
  if (who == 2) {
    r.authorization = "Bearer " + w.admin;
    r.method = "GET";  // reads only: no unbounded backups or users from the fuzzer
  }
  if (who == 3) r.authorization = "Bearer " + w.trainee;
  const size_t users = w.store->ListUsers().value().size();
  const http::HttpReply reply = w.api->Handle(r);
  static const std::set<int> kKnown = {200, 201, 204, 303, 400, 401, 403, 404, 409, 429, 503};
  VSURG_FUZZ_CHECK(kKnown.count(reply.status) == 1);
  if (reply.status >= 400 && reply.content_type == "application/json") {
    const auto j = nlohmann::json::parse(reply.body, nullptr, false);
    VSURG_FUZZ_CHECK(j.is_object() && j.contains("error"));
  }
  const bool api = r.target.rfind("/api/v1/", 0) == 0;
  if (who <= 1 && api && r.target.rfind("/api/v1/signin", 0) != 0)
    VSURG_FUZZ_CHECK(reply.status >= 400);
  if (who <= 1) VSURG_FUZZ_CHECK(w.store->ListUsers().value().size() == users);
  return 0;
}
