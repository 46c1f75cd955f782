// The dashboard's administration routes: users and their tokens, exports and backups.
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

}  // namespace vsurg::server::http
