// The dashboard's evaluation routes: an evaluator's submissions, reports, the training effect and
// weight sets.
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

}  // namespace vsurg::server::http
