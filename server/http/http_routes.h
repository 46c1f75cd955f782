// The dashboard's route handlers, one short function per route of HttpApi::kRoutes, and what
// each is given. Private to server/http: http_api.cpp routes and authorises, the handlers live
// by area (http_routes_sessions.cpp, _evaluation, _admin, _training).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "server/http/http_api.h"

namespace vsurg::server::http {

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

// The handlers, one per route (kRoutes).
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
  static HttpReply SessionGuidanceRoute(const Call& c);
  static HttpReply SessionGuide(const Call& c);
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

}  // namespace vsurg::server::http
