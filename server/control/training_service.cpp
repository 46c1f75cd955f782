// TrainingService over gRPC: requests to server/domain/training.h calls, results to messages.
#include "proto/convert/services.h"
#include "server/control/grpc_common.h"
#include "server/domain/training.h"

namespace vsurg::server::grpcapi {
namespace {

using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;

void ToProto(const ExerciseView& e, v1::Exercise* out) {
  out->set_id(e.record.id);
  out->set_position(e.record.position);
  out->set_title(e.record.title);
  out->set_scene(e.record.scene);
  for (size_t i = 0; i < e.spec.targets.size(); ++i) {
    v1::ExerciseTarget* t = out->add_targets();
    t->set_metric(e.spec.targets[i].metric);
    if (e.spec.targets[i].value) t->set_value(*e.spec.targets[i].value);
    t->set_from_experts(!e.spec.targets[i].value);
    if (e.targets[i].value) t->set_resolved(*e.targets[i].value);
    t->set_expert_trials(e.targets[i].expert_trials);
  }
  out->set_consecutive(e.spec.rule.consecutive);
  out->set_max_attempts_per_day(e.spec.rule.max_attempts_per_day);
  out->set_unlock_in_order(e.spec.unlock_in_order);
  out->set_benchmark(e.spec.benchmark == scoring::BenchmarkMode::kMeanSd ? "mean_sd"
                                                                         : "best_quartile");
  out->set_k(e.spec.k);
  convert::ToProto(e.spec.task, out->mutable_task());
}

void ToProto(const CourseView& c, v1::Course* out) {
  out->set_id(c.record.id);
  out->set_name(c.record.name);
  out->set_description(c.record.description);
  out->set_owner(c.record.owner);
  for (const ExerciseView& e : c.exercises) ToProto(e, out->add_exercises());
}

void ToProto(const scoring::TargetCheck& t, v1::TargetCheck* out) {
  out->set_metric(std::string(t.metric));
  out->set_value(t.value);
  out->set_target(t.target);
  out->set_met(t.met);
}

void ToProto(const db::CohortRecord& c, v1::Cohort* out) {
  out->set_id(c.id);
  out->set_name(c.name);
  out->set_instructor(c.instructor);
  for (const std::string& m : c.members) out->add_members(m);
}

void ToProto(const CourseView& c, const std::string& trainee, const ExerciseProgress& ep,
             v1::ExerciseProgress* out) {
  out->set_course_id(c.record.id);
  out->set_exercise_id(ep.exercise_id);
  for (const ExerciseView& e : c.exercises)
    if (e.record.id == ep.exercise_id) out->set_position(e.record.position);
  out->set_trainee(trainee);
  out->set_state(CellStateName(ep.state));
  out->set_attempts(ep.progress.attempts);
  out->set_passes(ep.progress.passes);
  out->set_streak(ep.progress.streak);
  out->set_proficient_at(ep.progress.proficient_at.value_or(0));
  out->set_proficient_us(ep.proficient_us);
  if (!ep.progress.checks.empty())
    for (const scoring::TargetCheck& t : ep.progress.checks.back().checks)
      ToProto(t, out->add_last());
}

// The request's exercise as the domain takes it (a target with a value is fixed, else from
// the experts).
Expected<NewExercise> FromProto(const v1::Exercise& e, size_t i) {
  NewExercise out{e.title(), e.scene(), {}};
  for (const v1::ExerciseTarget& t : e.targets()) {
    TargetSpec ts{t.metric(), std::nullopt};
    if (t.has_value()) ts.value = t.value();
    if (t.has_value() == t.from_experts())
      return InvalidArgument("exercises[" + std::to_string(i) + "].targets",
                             "each target has a value or from_experts, one of the two");
    out.spec.targets.push_back(std::move(ts));
  }
  // The one validation of a spec: through its JSON, as the HTTP API's bodies go.
  ExerciseSpec& s = out.spec;
  s.rule.consecutive = e.consecutive() ? e.consecutive() : 2;
  s.rule.max_attempts_per_day = e.max_attempts_per_day();
  s.unlock_in_order = e.unlock_in_order();
  if (e.benchmark() == "best_quartile") s.benchmark = scoring::BenchmarkMode::kBestQuartile;
  if (!e.benchmark().empty() && e.benchmark() != "mean_sd" && e.benchmark() != "best_quartile")
    return InvalidArgument("exercises[" + std::to_string(i) + "].benchmark",
                           "mean_sd or best_quartile");
  s.k = e.k() > 0 ? e.k() : 1.0;
  s.task = convert::FromProto(e.task());
  if ((s.task.target || s.task.tolerance) && !s.task.kind)
    return InvalidArgument("exercises[" + std::to_string(i) + "].task.kind",
                           "twist or press: the task the target and tolerance are for");
  auto checked = ParseExerciseSpec(ExerciseSpecJson(s));
  if (!checked.ok())
    return InvalidArgument("exercises[" + std::to_string(i) + "]." + checked.error().field,
                           checked.error().message);
  out.spec = std::move(checked).value();
  return out;
}

class TrainingServiceImpl final : public v1::TrainingService::CallbackService {
 public:
  TrainingServiceImpl(Domain& d, CallPool& pool) : d_(d), pool_(pool) {}

  ServerUnaryReactor* CreateCourse(CallbackServerContext* ctx, const v1::CreateCourseRequest* req,
                                   v1::Course* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingCreateCourse,
                 [=, this](const db::Principal& p) -> Status {
                   std::vector<NewExercise> exercises;
                   for (int i = 0; i < req->exercises_size(); ++i) {
                     auto e = FromProto(req->exercises(i), static_cast<size_t>(i));
                     if (!e.ok()) return e.error();
                     exercises.push_back(std::move(e).value());
                   }
                   auto c = server::CreateCourse(d_, p, req->name(), req->description(), exercises);
                   if (!c.ok()) return c.error();
                   ToProto(*c, resp);
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* CreateCohort(CallbackServerContext* ctx, const v1::CreateCohortRequest* req,
                                   v1::Cohort* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingCreateCohort,
                 [=, this](const db::Principal& p) -> Status {
                   std::vector<std::string> members(req->members().begin(), req->members().end());
                   auto c = server::CreateCohort(d_, p, req->name(), req->instructor(), members);
                   if (!c.ok()) return c.error();
                   ToProto(*c, resp);
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* Enrol(CallbackServerContext* ctx, const v1::EnrolRequest* req,
                            v1::Enrolment* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingEnrol,
                 [=, this](const db::Principal& p) -> Status {
                   db::EnrolmentRecord e;
                   e.course_id = req->course_id();
                   if (req->cohort_id() != 0) e.cohort_id = req->cohort_id();
                   e.trainee = req->trainee();
                   e.starts_us = req->starts_us();
                   if (req->ends_us() != 0) e.ends_us = req->ends_us();
                   auto made = server::Enrol(d_, p, e);
                   if (!made.ok()) return made.error();
                   resp->set_id(made->id);
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* SetExpert(CallbackServerContext* ctx, const v1::SetExpertRequest* req,
                                v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kTrainingSetExpert, [=, this](const db::Principal& p) {
      return server::SetExpert(d_, p, req->trainee(), req->expert());
    });
  }

  ServerUnaryReactor* Progress(CallbackServerContext* ctx, const v1::ProgressRequest* req,
                               v1::ProgressResponse* resp) override {
    return Unary(
        d_, pool_, ctx, Method::kTrainingProgress, [=, this](const db::Principal& p) -> Status {
          std::vector<CourseProgress> parts;
          if (req->cohort_id() != 0) {
            const GridPage page{.offset = req->offset(),
                                .limit = req->limit() == 0 ? kMaxGridTrainees : req->limit()};
            auto grid = CohortProgress(d_, p, req->cohort_id(), req->course_id(), page);
            if (!grid.ok()) return grid.error();
            resp->set_total_trainees(grid->total_trainees);
            parts.push_back(std::move(grid).value());
          } else {
            auto mine = TraineeCourses(d_, p, req->trainee().empty() ? p.name : req->trainee());
            if (!mine.ok()) return mine.error();
            parts = std::move(mine).value();
          }
          for (const CourseProgress& c : parts) {
            if (req->course_id() != 0 && c.course.record.id != req->course_id()) continue;
            for (const TraineeProgress& t : c.trainees)
              for (const ExerciseProgress& ep : t.exercises)
                ToProto(c.course, t.trainee, ep, resp->add_rows());
          }
          return Status::Ok();
        });
  }

  ServerUnaryReactor* Next(CallbackServerContext* ctx, const v1::NextExerciseRequest* req,
                           v1::NextExerciseResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingNext,
                 [=, this](const db::Principal& p) -> Status {
                   auto next = NextExerciseOf(d_, p, req->trainee());
                   if (!next.ok()) return next.error();
                   if (!next->course || !next->exercise_id) return Status::Ok();
                   resp->set_has_next(true);
                   ToProto(*next->course, resp->mutable_course());
                   resp->set_exercise_id(*next->exercise_id);
                   for (int64_t id : next->open) resp->add_open(id);
                   const std::string trainee = req->trainee().empty() ? p.name : req->trainee();
                   ToProto(*next->course, trainee, next->progress, resp->mutable_progress());
                   resp->set_may_attempt(next->progress.progress.may_attempt);
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* ListCourses(CallbackServerContext* ctx, const v1::ListCoursesRequest*,
                                  v1::ListCoursesResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingListCourses,
                 [=, this](const db::Principal& p) -> Status {
                   auto list = server::ListCourses(d_, p);
                   if (!list.ok()) return list.error();
                   for (const CourseView& c : *list) ToProto(c, resp->add_courses());
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* UpdateExercise(CallbackServerContext* ctx,
                                     const v1::UpdateExerciseRequest* req, v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kTrainingUpdateExercise,
                 [=, this](const db::Principal& p) -> Status {
                   auto e = FromProto(req->exercise(), 0);
                   if (!e.ok()) return e.error();
                   return SetExerciseSpec(d_, p, req->exercise_id(), e->spec);
                 });
  }

  ServerUnaryReactor* ListCohorts(CallbackServerContext* ctx, const v1::ListCohortsRequest*,
                                  v1::ListCohortsResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingListCohorts,
                 [=, this](const db::Principal& p) -> Status {
                   auto list = server::ListCohorts(d_, p);
                   if (!list.ok()) return list.error();
                   for (const db::CohortRecord& c : *list) ToProto(c, resp->add_cohorts());
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* AddMembers(CallbackServerContext* ctx, const v1::AddMembersRequest* req,
                                 v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kTrainingAddMembers, [=, this](const db::Principal& p) {
      return AddCohortMembers(d_, p, req->cohort_id(),
                              {req->members().begin(), req->members().end()});
    });
  }

  ServerUnaryReactor* Curve(CallbackServerContext* ctx, const v1::CurveRequest* req,
                            v1::CurveResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kTrainingCurve,
                 [=, this](const db::Principal& p) -> Status {
                   const std::string trainee = req->trainee().empty() ? p.name : req->trainee();
                   auto c = TraineeCurve(d_, p, trainee, req->exercise_id());
                   if (!c.ok()) return c.error();
                   const auto& checks = c->progress.progress.checks;
                   for (size_t i = 0; i < c->attempts.size() && i < checks.size(); ++i) {
                     v1::CurveAttempt* a = resp->add_attempts();
                     a->set_session_id(static_cast<uint64_t>(c->attempts[i].session_id));
                     a->set_ended_us(c->attempts[i].ended_us);
                     a->set_passed(checks[i].passed);
                     for (const scoring::TargetCheck& t : checks[i].checks)
                       ToProto(t, a->add_checks());
                     if (i < c->cusum.values.size()) a->set_cusum(c->cusum.values[i]);
                   }
                   const scoring::CusumParams& k = c->exercise.spec.cusum;
                   resp->set_p0(k.p0);
                   resp->set_p1(k.p1);
                   resp->set_alpha(k.alpha);
                   resp->set_beta(k.beta);
                   resp->set_s(c->cusum.limits.s);
                   resp->set_h0(c->cusum.limits.h0);
                   resp->set_h1(c->cusum.limits.h1);
                   resp->set_cusum_proficient_at(c->cusum.proficient_at.value_or(0));
                   resp->set_cusum_unacceptable_at(c->cusum.unacceptable_at.value_or(0));
                   ToProto(c->course, trainee, c->progress, resp->mutable_progress());
                   return Status::Ok();
                 });
  }

 private:
  Domain& d_;
  CallPool& pool_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewTrainingService(Domain& d, CallPool& pool) {
  return std::make_unique<TrainingServiceImpl>(d, pool);
}

}  // namespace vsurg::server::grpcapi
