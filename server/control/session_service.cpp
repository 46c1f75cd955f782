// SessionService over gRPC: requests to server/domain/api.h calls, results to messages.
#include "server/control/grpc_common.h"
#include "server/domain/scene_catalog.h"
#include "server/domain/training.h"

namespace vsurg::server::grpcapi {
namespace {

using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;

class SessionServiceImpl final : public v1::SessionService::CallbackService {
 public:
  SessionServiceImpl(Domain& d, CallPool& pool) : d_(d), pool_(pool) {}

  ServerUnaryReactor* Create(CallbackServerContext* ctx, const v1::CreateSessionRequest* req,
                             v1::CreateSessionResponse* resp) override {
    return Unary(
        d_, pool_, ctx, Method::kSessionCreate, [=, this](const db::Principal& p) -> Status {
          auto created = req->exercise_id() != 0
                             ? CreateExerciseSession(d_, p, req->trainee(), req->exercise_id())
                             : CreateSession(d_, p, req->trainee(), req->scene());
          if (!created.ok()) return created.error();
          Credentials(*created, resp);
          return Status::Ok();
        });
  }

  ServerUnaryReactor* Join(CallbackServerContext* ctx, const v1::JoinRequest* req,
                           v1::CreateSessionResponse* resp) override {
    if (req->role() == v1::ROLE_INSTRUCTOR) return JoinInstructor(ctx, req, resp);
    return Unary(d_, pool_, ctx, Method::kSessionJoin, [=, this](const db::Principal& p) -> Status {
      auto joined = JoinSession(d_, p, req->id(), req->with_surface());
      if (!joined.ok()) return joined.error();
      if (!req->with_surface()) joined->surface.reset(), joined->needle.reset();
      Credentials(*joined, resp);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* Guide(CallbackServerContext* ctx, const v1::GuideRequest* req,
                            v1::Guidance* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionGuide, [=, this](const db::Principal& p) {
      return AnswerGuidance(
          GuideSession(d_, p, req->id(), {GuideModeFromProto(req->mode()), req->alpha()}), resp);
    });
  }

  ServerUnaryReactor* GetGuidance(CallbackServerContext* ctx, const v1::SessionRef* req,
                                  v1::Guidance* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionGet, [=, this](const db::Principal& p) {
      return AnswerGuidance(server::GetGuidance(d_, p, req->id()), resp);
    });
  }

  ServerUnaryReactor* Start(CallbackServerContext* ctx, const v1::SessionRef* req,
                            v1::Session* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionStart, [=, this](const db::Principal& p) {
      return Answer(StartSession(d_, p, req->id()), resp);
    });
  }

  ServerUnaryReactor* Stop(CallbackServerContext* ctx, const v1::StopSessionRequest* req,
                           v1::Session* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionStop, [=, this](const db::Principal& p) {
      if (Status s = Answer(StopSession(d_, p, req->id(), req->reason()), resp); !s.ok()) return s;
      AddPalpation(p, resp);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* Get(CallbackServerContext* ctx, const v1::SessionRef* req,
                          v1::Session* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionGet, [=, this](const db::Principal& p) -> Status {
      auto v = GetSessionWithTargets(d_, p, req->id());
      if (!v.ok()) return v.error();
      if (Status s = Answer(v->view, resp); !s.ok()) return s;
      // An attempt at an exercise: its checks against the targets (the station's summary).
      if (const auto& checks = v->targets) {
        for (const scoring::TargetCheck& t : checks->checks) {
          v1::TargetCheck* x = resp->add_targets();
          x->set_metric(std::string(t.metric));
          x->set_value(t.value);
          x->set_target(t.target);
          x->set_met(t.met);
        }
        resp->set_targets_passed(checks->passed);
      }
      AddPalpation(p, resp);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* List(CallbackServerContext* ctx, const v1::ListSessionsRequest* req,
                           v1::ListSessionsResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionList, [=, this](const db::Principal& p) -> Status {
      auto list = ListSessions(d_, p, req->trainee(), req->live_only());
      if (!list.ok()) return list.error();
      for (const SessionView& v : *list) ToProto(v, resp->add_sessions());
      return Status::Ok();
    });
  }

  ServerUnaryReactor* ListScenes(CallbackServerContext* ctx, const v1::ListScenesRequest*,
                                 v1::ListScenesResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kSessionListScenes,
                 [=, this](const db::Principal& p) -> Status {
                   auto listing = server::ListScenes(d_, p);
                   if (!listing.ok()) return listing.error();
                   for (const SceneInfo& s : listing->scenes) {
                     v1::SceneInfo* info = resp->add_scenes();
                     info->set_name(s.name);
                     info->set_description(s.description);
                     info->set_model(s.model);
                     info->set_task(s.task);
                     info->set_error_budget_rms(s.error_budget_rms);
                   }
                   for (const std::string& why : listing->unusable) resp->add_unusable(why);
                   return Status::Ok();
                 });
  }

 private:
  // An ended palpation's lumps and marks (the station's summary draws them). A record that cannot
  // be read leaves them out: the answer is the session's, the drawing an extra.
  void AddPalpation(const db::Principal& p, v1::Session* resp) {
    // A palpation's own figures (0 for the other tasks): no record is read for the others.
    const v1::TrialMetrics& m = resp->metrics();
    if (!resp->has_metrics() ||
        (m.lumps() == 0 && m.false_marks() == 0 && m.coverage() == 0 && m.mean_force_n() == 0))
      return;
    auto outcome = SessionPalpation(d_, p, resp->id());
    if (outcome.ok() && outcome->has_value())
      convert::ToProto(**outcome, resp->mutable_palpation());
  }

  // Four-handed training: an instructor's station's credentials for its own channel.
  ServerUnaryReactor* JoinInstructor(CallbackServerContext* ctx, const v1::JoinRequest* req,
                                     v1::CreateSessionResponse* resp) {
    return Unary(d_, pool_, ctx, Method::kSessionJoinInstructor,
                 [=, this](const db::Principal& p) -> Status {
                   auto joined = JoinAsInstructor(d_, p, req->id(),
                                                  {GuideModeFromProto(req->mode()), req->alpha()});
                   if (!joined.ok()) return joined.error();
                   Credentials(*joined, resp);
                   return Status::Ok();
                 });
  }
  static Status AnswerGuidance(const Expected<SessionGuidance>& g, v1::Guidance* resp) {
    if (!g.ok()) return g.error();
    ToProto(*g, resp);
    return Status::Ok();
  }
  static void Credentials(const CreatedSession& c, v1::CreateSessionResponse* resp) {
    ToProto(c.record, resp->mutable_session());
    resp->set_udp_host(c.udp_host);
    resp->set_udp_port(c.udp_port);
    resp->set_session_key(std::string(c.key.begin(), c.key.end()));
    if (c.surface) convert::ToProto(*c.surface, resp->mutable_surface());
    if (c.needle) convert::ToProto(*c.needle, resp->mutable_needle());
    if (c.blade) convert::ToProto(*c.blade, resp->mutable_blade());
    resp->set_channel(c.channel);
    if (c.second_channel != 0) {
      resp->set_second_channel(c.second_channel);
      resp->set_second_key(std::string(c.second_key.begin(), c.second_key.end()));
    }
  }
  static Status Answer(const Expected<SessionView>& v, v1::Session* resp) {
    if (!v.ok()) return v.error();
    ToProto(*v, resp);
    return Status::Ok();
  }
  Domain& d_;
  CallPool& pool_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewSessionService(Domain& d, CallPool& pool) {
  return std::make_unique<SessionServiceImpl>(d, pool);
}

}  // namespace vsurg::server::grpcapi
