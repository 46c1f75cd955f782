#include "server/http/http_reply.h"

#include "common/core/time.h"
#include "server/http/web_assets.h"

namespace vsurg::server::http {

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

std::optional<int64_t> QueryNumber(const std::multimap<std::string, std::string>& q,
                                   const char* name) {
  const std::string v = Param(q, name);
  if (v.empty()) return 0;
  const auto id = ParseId(v);
  if (!id || *id > static_cast<uint64_t>(INT64_MAX)) return std::nullopt;
  return static_cast<int64_t>(*id);
}

std::optional<int64_t> QueryTime(const std::multimap<std::string, std::string>& q,
                                 const char* name) {
  const std::string v = Param(q, name);
  if (v.empty()) return 0;
  if (auto iso = ParseIsoUtc(v, name); iso.ok()) return *iso;
  return QueryNumber(q, name);
}

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

}  // namespace vsurg::server::http
