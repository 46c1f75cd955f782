#include "server/control/control_plane.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/core/file.h"
#include "common/scoring/evaluation.h"
#include "common/scoring/report_json.h"
#include "common/sim/scene.h"
#include "db/store.h"
#include "server/control/auth.h"
#include "server/session/session_manager.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::server {
namespace {

namespace v1 = vsurg::v1;
using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;

// The one place where our errors become gRPC statuses.
grpc::Status ToGrpcStatus(const Error& e) {
  grpc::StatusCode code = grpc::StatusCode::INTERNAL;
  switch (e.code) {
    case ErrorCode::kInvalidArgument:
    case ErrorCode::kParseError:
      code = grpc::StatusCode::INVALID_ARGUMENT;
      break;
    case ErrorCode::kNotFound:
      code = grpc::StatusCode::NOT_FOUND;
      break;
    case ErrorCode::kAlreadyExists:
      code = grpc::StatusCode::ALREADY_EXISTS;
      break;
    case ErrorCode::kFailedPrecondition:
      code = grpc::StatusCode::FAILED_PRECONDITION;
      break;
    case ErrorCode::kUnavailable:
      code = grpc::StatusCode::UNAVAILABLE;
      break;
    case ErrorCode::kResourceExhausted:
      code = grpc::StatusCode::RESOURCE_EXHAUSTED;
      break;
    case ErrorCode::kUnauthenticated:
      code = grpc::StatusCode::UNAUTHENTICATED;
      break;
    case ErrorCode::kPermissionDenied:
      code = grpc::StatusCode::PERMISSION_DENIED;
      break;
    case ErrorCode::kIoError:
    case ErrorCode::kNumerical:
      code = grpc::StatusCode::INTERNAL;
      break;
  }
  return grpc::Status(code, e.field.empty() ? e.message : e.field + ": " + e.message);
}

grpc::Status ToGrpcStatus(const Status& s) {
  return s.ok() ? grpc::Status::OK : ToGrpcStatus(s.error());
}

Error Denied(const std::string& what) {
  return Error{ErrorCode::kPermissionDenied, what, ""};
}

struct Shared {
  db::Store& store;
  SessionManager& sessions;
  ControlPlaneOptions options;
};

Expected<db::Principal> Authorize(Shared& sh, CallbackServerContext* ctx, Method m) {
  const auto& md = ctx->client_metadata();
  const auto it = md.find("authorization");
  if (it == md.end())
    return Error{ErrorCode::kUnauthenticated, "missing 'authorization: Bearer <token>' metadata",
                 ""};
  const auto token = BearerToken(std::string_view(it->second.data(), it->second.size()));
  if (!token)
    return Error{ErrorCode::kUnauthenticated, "malformed authorization: expected 'Bearer <token>'",
                 ""};
  auto p = sh.store.Authenticate(*token);
  if (!p.ok()) {
    if (p.error().code == ErrorCode::kUnauthenticated) return p.error();
    return Error{ErrorCode::kUnavailable, "cannot check credentials: " + p.error().message, ""};
  }
  if (!RoleMay(p->role, m))
    return Denied(std::string("role ") + db::RoleName(p->role) + " may not call " + MethodName(m));
  return p;
}

// A unary call whose body runs to completion on the calling thread.
template <class Body>
ServerUnaryReactor* Unary(Shared& sh, CallbackServerContext* ctx, Method m, Body&& body) {
  ServerUnaryReactor* r = ctx->DefaultReactor();
  auto p = Authorize(sh, ctx, m);
  if (!p.ok()) {
    r->Finish(ToGrpcStatus(p.error()));
    return r;
  }
  r->Finish(ToGrpcStatus(body(*p)));
  return r;
}

v1::SessionState StateToProto(const std::string& s) {
  static const std::map<std::string, v1::SessionState> kStates = {
      {"created", v1::SESSION_STATE_CREATED},           {"running", v1::SESSION_STATE_RUNNING},
      {"stalled", v1::SESSION_STATE_STALLED},           {"ended", v1::SESSION_STATE_ENDED},
      {"disconnected", v1::SESSION_STATE_DISCONNECTED}, {"aborted", v1::SESSION_STATE_ABORTED}};
  const auto it = kStates.find(s);
  return it == kStates.end() ? v1::SESSION_STATE_UNSPECIFIED : it->second;
}

void ToProto(const db::SessionRecord& r, v1::Session* out) {
  out->set_id(static_cast<uint64_t>(r.id));
  out->set_trainee(r.trainee);
  out->set_scene(r.scene);
  out->set_state(StateToProto(r.state));
  out->set_created_us(r.created_us);
  out->set_started_us(r.started_us);
  out->set_ended_us(r.ended_us);
  out->set_end_reason(r.end_reason);
}

void ToProto(const SessionTelemetry& t, v1::Telemetry* out) {
  out->set_session_id(t.id);
  out->set_server_time_us(t.server_time_us);
  out->set_state(StateToProto(t.state));
  out->mutable_force()->set_x(t.sim.force.x());
  out->mutable_force()->set_y(t.sim.force.y());
  out->mutable_force()->set_z(t.sim.force.z());
  out->set_twist(t.sim.twist);
  out->set_torque(t.sim.torque);
  out->set_contact(t.sim.contact);
  out->set_grasping(t.sim.grasping);
  v1::TrialMetrics* m = out->mutable_metrics();
  m->set_completed(t.sim.metrics.completed);
  m->set_completion_time_s(t.sim.metrics.completion_time);
  m->set_task_error(t.sim.metrics.task_error);
  m->set_peak_force_n(t.sim.metrics.peak_force);
  m->set_time_over_force_limit_s(t.sim.metrics.time_over_force_limit);
  m->set_path_length_m(t.sim.metrics.path_length);
  m->set_rms_jerk(t.sim.metrics.rms_jerk);
  m->set_overload_events(t.sim.metrics.overload_events);
  m->set_duration_s(t.sim.metrics.duration);
  m->set_score(t.sim.metrics.score);
  m->set_raw_score(t.sim.metrics.raw_score);
  m->set_caps(t.sim.metrics.caps);
  out->set_rtt_us(t.rtt_us);
  out->set_packet_loss(t.packet_loss);
  out->set_packets(t.packets);
  out->set_haptic_rate_hz(t.haptic_rate_hz);
  out->mutable_tip()->set_x(t.sim.tip.x());
  out->mutable_tip()->set_y(t.sim.tip.y());
  out->mutable_tip()->set_z(t.sim.tip.z());
  out->set_scene(t.scene);
  if (t.has_surface) {
    v1::SurfaceState* surface = out->mutable_surface();
    surface->set_frame_id(t.surface_frame);
    surface->mutable_indices()->Assign(t.surface_indices.begin(), t.surface_indices.end());
    auto* p = surface->mutable_positions();
    p->Reserve(static_cast<int>(3 * t.surface_positions.size()));
    for (const geometry::Vec3& v : t.surface_positions)
      for (int k = 0; k < 3; ++k) p->Add(static_cast<float>(v[k]));
  }
}

// The scoring loop's metrics of an ended session, when recorded.
Status AddMetrics(db::Store& store, v1::Session* out) {
  auto m = store.GetTrialMetrics(static_cast<int64_t>(out->id()));
  if (!m.ok()) return m.error();
  if (!m->has_value()) return Status::Ok();
  const db::TrialMetricsRecord& r = **m;
  v1::TrialMetrics* t = out->mutable_metrics();
  t->set_completed(r.completed);
  t->set_completion_time_s(r.completion_time_s);
  t->set_task_error(r.task_error);
  t->set_peak_force_n(r.peak_force_n);
  t->set_time_over_force_limit_s(r.time_over_force_limit_s);
  t->set_path_length_m(r.path_length_m);
  t->set_rms_jerk(r.rms_jerk);
  t->set_overload_events(r.overload_events);
  t->set_duration_s(r.duration_s);
  t->set_score(r.score);
  t->set_raw_score(r.raw_score);
  t->set_caps(r.caps);
  return Status::Ok();
}

// A server-streaming call refused before it starts: it only reports the status.
template <class Message>
class Refuse final : public grpc::ServerWriteReactor<Message> {
 public:
  explicit Refuse(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

// A trainee may touch only their own sessions.
Status OwnSession(const db::Principal& p, const db::SessionRecord& r) {
  if (p.role == db::Role::kTrainee && r.trainee != p.name)
    return Denied("session " + std::to_string(r.id) + " belongs to another trainee");
  return Status::Ok();
}

// --- SessionService ---

class SessionServiceImpl final : public v1::SessionService::CallbackService {
 public:
  explicit SessionServiceImpl(Shared& sh) : sh_(sh) {}

  ServerUnaryReactor* Create(CallbackServerContext* ctx, const v1::CreateSessionRequest* req,
                             v1::CreateSessionResponse* resp) override {
    return Unary(sh_, ctx, Method::kSessionCreate, [&](const db::Principal& p) -> Status {
      std::string trainee = req->trainee();
      if (trainee.empty()) {
        if (p.role != db::Role::kTrainee)
          return InvalidArgument("trainee", "required (the trainee the session is for)");
        trainee = p.name;
      }
      if (p.role == db::Role::kTrainee && trainee != p.name)
        return Denied("a trainee creates sessions only for themself");
      auto created = sh_.sessions.Create(trainee, req->scene());
      if (!created.ok()) return created.error();
      ToProto(created->record, resp->mutable_session());
      resp->set_udp_host(created->udp_host);
      resp->set_udp_port(created->udp_port);
      resp->set_session_key(std::string(created->key.begin(), created->key.end()));
      return Status::Ok();
    });
  }

  ServerUnaryReactor* Start(CallbackServerContext* ctx, const v1::SessionRef* req,
                            v1::Session* resp) override {
    return Unary(sh_, ctx, Method::kSessionStart, [&](const db::Principal& p) -> Status {
      if (Status s = Check(p, req->id()); !s.ok()) return s;
      auto r = sh_.sessions.Start(req->id());
      if (!r.ok()) return r.error();
      ToProto(*r, resp);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* Stop(CallbackServerContext* ctx, const v1::StopSessionRequest* req,
                           v1::Session* resp) override {
    return Unary(sh_, ctx, Method::kSessionStop, [&](const db::Principal& p) -> Status {
      if (Status s = Check(p, req->id()); !s.ok()) return s;
      if (req->reason().size() > 256) return InvalidArgument("reason", "at most 256 characters");
      auto r = sh_.sessions.Stop(req->id(), req->reason());
      if (!r.ok()) return r.error();
      ToProto(*r, resp);
      return AddMetrics(sh_.store, resp);
    });
  }

  ServerUnaryReactor* Get(CallbackServerContext* ctx, const v1::SessionRef* req,
                          v1::Session* resp) override {
    return Unary(sh_, ctx, Method::kSessionGet, [&](const db::Principal& p) -> Status {
      auto r = sh_.sessions.Get(req->id());
      if (!r.ok()) return r.error();
      if (Status s = OwnSession(p, *r); !s.ok()) return s;
      ToProto(*r, resp);
      return AddMetrics(sh_.store, resp);
    });
  }

  ServerUnaryReactor* List(CallbackServerContext* ctx, const v1::ListSessionsRequest* req,
                           v1::ListSessionsResponse* resp) override {
    return Unary(sh_, ctx, Method::kSessionList, [&](const db::Principal& p) -> Status {
      std::optional<std::string> trainee;
      if (!req->trainee().empty()) trainee = req->trainee();
      if (p.role == db::Role::kTrainee) {
        if (trainee && *trainee != p.name) return Denied("a trainee lists only their sessions");
        trainee = p.name;
      }
      auto list = sh_.store.ListSessions(trainee);
      if (!list.ok()) return list.error();
      for (db::SessionRecord& r : *list) {
        if (sh_.sessions.IsLive(static_cast<uint64_t>(r.id))) {
          auto live = sh_.sessions.Get(static_cast<uint64_t>(r.id));
          if (live.ok()) r = *live;
        }
        const bool is_live = r.state == "created" || r.state == "running" || r.state == "stalled";
        if (req->live_only() && !is_live) continue;
        v1::Session* out = resp->add_sessions();
        ToProto(r, out);
        if (!is_live)
          if (Status s = AddMetrics(sh_.store, out); !s.ok()) return s;
      }
      return Status::Ok();
    });
  }

  ServerUnaryReactor* ListScenes(CallbackServerContext* ctx, const v1::ListScenesRequest*,
                                 v1::ListScenesResponse* resp) override {
    return Unary(sh_, ctx, Method::kSessionListScenes, [&](const db::Principal&) -> Status {
      std::error_code ec;
      std::vector<std::filesystem::path> files;
      for (const auto& entry : std::filesystem::directory_iterator(sim::ScenesDirectory(), ec))
        if (entry.path().extension() == ".json") files.push_back(entry.path());
      if (ec) return Error{ErrorCode::kUnavailable, "cannot read the scenes folder", "scenes"};
      std::sort(files.begin(), files.end());
      for (const auto& file : files) {
        auto scene = sim::LoadScene(file.string());
        if (!scene.ok()) {
          // Not offered (a station could not load it either), and said why; the rest still are.
          // Named by its file name: the message's own prefix is the server's full path.
          std::string why = scene.error().message;
          if (why.rfind(file.string() + ": ", 0) == 0) why.erase(0, file.string().size() + 2);
          resp->add_unusable(file.filename().string() + ": " + why);
          continue;
        }
        v1::SceneInfo* info = resp->add_scenes();
        info->set_name(file.stem().string());  // what Create and the stations resolve
        info->set_description(scene->description);
        info->set_model(sim::ModelKindName(scene->region.kind));
        info->set_task(scene->task.kind == scoring::TaskKind::kTwist ? "twist" : "press");
        info->set_error_budget_rms(scene->error_budget_rms);
      }
      return Status::Ok();
    });
  }

 private:
  Status Check(const db::Principal& p, uint64_t id) {
    auto r = sh_.store.GetSession(static_cast<int64_t>(id));
    if (!r.ok()) return r.error();
    return OwnSession(p, *r);
  }
  Shared& sh_;
};

// --- MonitorService ---

// One monitor stream. The sessions' sampler thread delivers the latest telemetry into a mailbox
// (one message per session, latest wins); a write starts only when none is in flight. Reactor
// callbacks take the mailbox mutex only to swap messages and never call into gRPC with it held.
class WatchReactor final : public grpc::ServerWriteReactor<v1::Telemetry> {
 public:
  WatchReactor(SessionManager& sessions, uint64_t session, double rate_hz)
      : sessions_(sessions), interval_s_(1.0 / rate_hz) {
    token_ = sessions_.Subscribe(session, [this](const std::vector<SessionTelemetry>& list,
                                                 bool ended) { Deliver(list, ended); });
  }

  void OnWriteDone(bool ok) override {
    std::unique_lock lock(mutex_);
    writing_ = false;
    if (!ok) {
      FinishLocked(lock, grpc::Status(grpc::StatusCode::UNAVAILABLE, "the monitor went away"));
      return;
    }
    Pump(lock);
  }

  void OnCancel() override {
    std::unique_lock lock(mutex_);
    FinishLocked(lock, grpc::Status::CANCELLED);
  }

  void OnDone() override {
    sessions_.Unsubscribe(token_);  // waits for a delivery in progress
    delete this;
  }

 private:
  void Deliver(const std::vector<SessionTelemetry>& list, bool ended) {
    std::unique_lock lock(mutex_);
    if (finished_) return;
    if (ended) {
      end_ = true;
    } else {
      const auto now = std::chrono::steady_clock::now();
      if (std::chrono::duration<double>(now - last_).count() < interval_s_ * 0.9) return;
      last_ = now;
      for (const SessionTelemetry& t : list) ToProto(t, &pending_[t.id]);
    }
    Pump(lock);
  }

  void Pump(std::unique_lock<std::mutex>& lock) {
    if (writing_ || finished_) return;
    if (!pending_.empty()) {
      inflight_.Swap(&pending_.begin()->second);
      pending_.erase(pending_.begin());
      writing_ = true;
      lock.unlock();
      StartWrite(&inflight_);
      return;
    }
    if (end_) FinishLocked(lock, grpc::Status::OK);  // the session ended: the stream ends
  }

  void FinishLocked(std::unique_lock<std::mutex>& lock, const grpc::Status& s) {
    if (finished_) return;
    finished_ = true;
    lock.unlock();
    Finish(s);
  }

  SessionManager& sessions_;
  double interval_s_;
  uint64_t token_ = 0;
  std::mutex mutex_;
  std::map<uint64_t, v1::Telemetry> pending_;
  v1::Telemetry inflight_;
  bool writing_ = false, finished_ = false, end_ = false;
  std::chrono::steady_clock::time_point last_{};
};

class MonitorServiceImpl final : public v1::MonitorService::CallbackService {
 public:
  explicit MonitorServiceImpl(Shared& sh) : sh_(sh) {}

  grpc::ServerWriteReactor<v1::Telemetry>* Watch(CallbackServerContext* ctx,
                                                 const v1::WatchRequest* req) override {
    auto p = Authorize(sh_, ctx, Method::kMonitorWatch);
    Status s = p.ok() ? Status::Ok() : Status(p.error());
    const double hz = req->rate_hz() == 0 ? 30.0 : req->rate_hz();
    if (s.ok() && !(hz >= 1 && hz <= 60)) s = InvalidArgument("rate_hz", "must be within 1..60");
    if (s.ok() && req->session_id() != 0 && !sh_.sessions.IsLive(req->session_id())) {
      auto r = sh_.store.GetSession(static_cast<int64_t>(req->session_id()));
      s = r.ok() ? Status(Error{ErrorCode::kFailedPrecondition,
                                "session " + std::to_string(req->session_id()) + " is " + r->state +
                                    ", not live",
                                "session_id"})
                 : Status(r.error());
    }
    if (!s.ok()) {
      return new Refuse<v1::Telemetry>(ToGrpcStatus(s));
    }
    return new WatchReactor(sh_.sessions, req->session_id(), hz);
  }

 private:
  Shared& sh_;
};

// --- EvaluationService ---

Expected<scoring::WeightSet> LoadWeights(db::Store& store, const std::string& name) {
  if (name.empty()) return scoring::WeightSet{};
  auto json = store.GetWeightSet(name);
  if (!json.ok()) return json.error();
  return scoring::WeightSetFromJsonText(*json);
}

Expected<std::vector<scoring::Rating>> ToRatings(const std::vector<db::RatingRow>& rows) {
  std::vector<scoring::Rating> out;
  for (const db::RatingRow& r : rows) {
    scoring::Rating x;
    x.evaluator = r.evaluator;
    auto g = scoring::ParseGroup(r.evaluator_group);
    if (!g) return Error{ErrorCode::kIoError, "stored group '" + r.evaluator_group + "'", ""};
    x.group = *g;
    x.scores = r.scores;
    out.push_back(std::move(x));
  }
  return out;
}

class EvaluationServiceImpl final : public v1::EvaluationService::CallbackService {
 public:
  explicit EvaluationServiceImpl(Shared& sh) : sh_(sh) {}

  ServerUnaryReactor* Submit(CallbackServerContext* ctx, const v1::SubmitEvaluationRequest* req,
                             v1::SubmitEvaluationResponse* resp) override {
    ServerUnaryReactor* r = ctx->DefaultReactor();
    auto p = Authorize(sh_, ctx, Method::kEvaluationSubmit);
    if (!p.ok()) {
      r->Finish(ToGrpcStatus(p.error()));
      return r;
    }
    db::Submission s;
    s.idempotency_key = req->idempotency_key();
    s.evaluator = req->evaluator();
    s.evaluator_group = req->evaluator_group();
    s.subject = req->subject();
    s.submitted_by = p->name;
    if (req->has_moment_min()) s.moment_min = req->moment_min();
    Status bad;
    if (p->role == db::Role::kEvaluator) {
      // Evaluators submit as themselves, in their own group.
      if (s.evaluator.empty()) s.evaluator = p->name;
      if (s.evaluator_group.empty()) s.evaluator_group = p->group;
      if (s.evaluator != p->name) bad = Denied("an evaluator submits only their own scores");
    } else if (s.evaluator.empty()) {
      bad = InvalidArgument("evaluator", "required when importing on an evaluator's behalf");
    }
    const auto kind = db::ParseSubjectKind(req->subject_kind());
    if (bad.ok() && !kind)
      bad = InvalidArgument("subject_kind", "unknown subject kind '" + req->subject_kind() +
                                                "' (session, trainee or model)");
    if (bad.ok() && req->scores_size() != db::kIndexes)
      bad = InvalidArgument("scores", "exactly 9 index scores are required, got " +
                                          std::to_string(req->scores_size()));
    if (!bad.ok()) {
      r->Finish(ToGrpcStatus(bad));
      return r;
    }
    s.subject_kind = *kind;
    for (int j = 0; j < db::kIndexes; ++j) s.scores[j] = req->scores(j);
    // Finishes from the store's writer thread once the group commit is on disk.
    sh_.store.SubmitEvaluationAsync(std::move(s), [r, resp](Expected<db::SubmitResult> res) {
      if (!res.ok()) {
        r->Finish(ToGrpcStatus(res.error()));
        return;
      }
      resp->set_submission_id(static_cast<uint64_t>(res->submission_id));
      resp->set_submitted_us(res->submitted_us);
      resp->set_duplicate(res->duplicate);
      r->Finish(grpc::Status::OK);
    });
    return r;
  }

  ServerUnaryReactor* Report(CallbackServerContext* ctx, const v1::ReportRequest* req,
                             v1::ReportResponse* resp) override {
    return Unary(sh_, ctx, Method::kEvaluationReport, [&](const db::Principal&) -> Status {
      const auto kind = db::ParseSubjectKind(req->subject_kind());
      if (!kind) return InvalidArgument("subject_kind", "session, trainee or model");
      if (req->subjects_size() < 1 || req->subjects_size() > 32)
        return InvalidArgument("subjects", "1 to 32 subjects");
      auto weights = LoadWeights(sh_.store, req->weight_set());
      if (!weights.ok()) return weights.error();
      std::vector<scoring::SubjectRatings> subjects;
      for (const std::string& subject : req->subjects()) {
        auto rows = sh_.store.LoadRatings(*kind, subject);
        if (!rows.ok()) return rows.error();
        if (rows->empty())
          return Error{ErrorCode::kNotFound,
                       "no evaluations of " + req->subject_kind() + " '" + subject + "'",
                       "subjects"};
        auto ratings = ToRatings(*rows);
        if (!ratings.ok()) return ratings.error();
        subjects.push_back({subject, std::move(ratings).value()});
      }
      nlohmann::json j;
      if (subjects.size() == 1) {
        auto rep = scoring::Evaluate(subjects[0].ratings, *weights);
        if (!rep.ok()) return rep.error();
        j = scoring::ReportToJson(*rep);
        j["subject"] = subjects[0].subject;
      } else {
        auto cmp = scoring::Compare(subjects, *weights);
        if (!cmp.ok()) return cmp.error();
        std::vector<std::string> names;
        for (const auto& s : subjects) names.push_back(s.subject);
        j = scoring::ComparisonToJson(*cmp, names);
      }
      j["subject_kind"] = req->subject_kind();
      const std::string text = j.dump();
      // Recorded with the weights it used (a report can always be explained later).
      if (Status s = sh_.store.RecordReport(req->subject_kind(), req->subjects(0),
                                            scoring::WeightSetToJson(*weights).dump(), text);
          !s.ok())
        return s;
      resp->set_report_json(text);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* TrainingEffect(CallbackServerContext* ctx,
                                     const v1::TrainingEffectRequest* req,
                                     v1::TrainingEffectResponse* resp) override {
    return Unary(sh_, ctx, Method::kEvaluationTrainingEffect, [&](const db::Principal&) -> Status {
      auto weights = LoadWeights(sh_.store, req->weight_set());
      if (!weights.ok()) return weights.error();
      auto rows = sh_.store.LoadTrainingRows();
      if (!rows.ok()) return rows.error();
      // Each evaluator's score of a trainee is their comprehensive score (eq. 11 weights).
      std::vector<scoring::TrainingScore> scores;
      for (const db::TrainingRow& t : *rows) {
        double n = 0;
        for (int j = 0; j < db::kIndexes; ++j) n += weights->index[j] * t.scores[j];
        scores.push_back({t.trainee, t.trainee_group, t.moment_min, t.evaluator, n});
      }
      auto cells = scoring::TrainingEffect(scores);
      if (!cells.ok()) return cells.error();
      resp->set_cells_json(scoring::TrainingToJson(*cells).dump());
      return Status::Ok();
    });
  }

 private:
  Shared& sh_;
};

// --- AdminService ---

std::optional<db::Role> RoleFromProto(v1::Role r) {
  switch (r) {
    case v1::ROLE_TRAINEE:
      return db::Role::kTrainee;
    case v1::ROLE_INSTRUCTOR:
      return db::Role::kInstructor;
    case v1::ROLE_EVALUATOR:
      return db::Role::kEvaluator;
    case v1::ROLE_ADMIN:
      return db::Role::kAdmin;
    default:
      return std::nullopt;
  }
}

v1::Role RoleToProto(db::Role r) {
  switch (r) {
    case db::Role::kTrainee:
      return v1::ROLE_TRAINEE;
    case db::Role::kInstructor:
      return v1::ROLE_INSTRUCTOR;
    case db::Role::kEvaluator:
      return v1::ROLE_EVALUATOR;
    case db::Role::kAdmin:
      return v1::ROLE_ADMIN;
  }
  return v1::ROLE_UNSPECIFIED;
}

// Streams an export: a producer thread formats chunks and waits for each write to complete
// (flow control); the reactor callbacks only flip flags under the mutex.
class ExportReactor final : public grpc::ServerWriteReactor<v1::ExportChunk> {
 public:
  ExportReactor(db::Store& store, db::ExportFilter filter, db::ExportFormat format) {
    thread_ = std::thread([this, &store, filter, format] {
      Status s = store.Export(filter, format, [this](std::string_view chunk) {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [this] { return !writing_ || broken_; });
        if (broken_) return false;
        chunk_.set_data(chunk.data(), chunk.size());
        writing_ = true;
        lock.unlock();
        StartWrite(&chunk_);
        return true;
      });
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return !writing_ || broken_; });
      const bool broken = broken_;
      lock.unlock();
      Finish(broken ? grpc::Status::CANCELLED : ToGrpcStatus(s));
    });
  }
  void OnWriteDone(bool ok) override {
    {
      std::lock_guard lock(mutex_);
      writing_ = false;
      if (!ok) broken_ = true;
    }
    cv_.notify_all();
  }
  void OnCancel() override {
    {
      std::lock_guard lock(mutex_);
      broken_ = true;
    }
    cv_.notify_all();
  }
  void OnDone() override {
    thread_.join();  // its last act was Finish
    delete this;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool writing_ = false, broken_ = false;
  v1::ExportChunk chunk_;
  std::thread thread_;
};

class AdminServiceImpl final : public v1::AdminService::CallbackService {
 public:
  explicit AdminServiceImpl(Shared& sh) : sh_(sh) {}

  ServerUnaryReactor* CreateUser(CallbackServerContext* ctx, const v1::CreateUserRequest* req,
                                 v1::User* resp) override {
    return Unary(sh_, ctx, Method::kAdminCreateUser, [&](const db::Principal&) -> Status {
      const auto role = RoleFromProto(req->role());
      if (!role) return InvalidArgument("role", "trainee, instructor, evaluator or admin");
      auto u = sh_.store.CreateUser(req->name(), *role, req->group());
      if (!u.ok()) return u.error();
      resp->set_name(u->name);
      resp->set_role(RoleToProto(u->role));
      resp->set_group(u->group);
      resp->set_created_us(u->created_us);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* IssueToken(CallbackServerContext* ctx, const v1::IssueTokenRequest* req,
                                 v1::IssueTokenResponse* resp) override {
    return Unary(sh_, ctx, Method::kAdminIssueToken, [&](const db::Principal&) -> Status {
      auto t = sh_.store.IssueToken(req->user(), req->label());
      if (!t.ok()) return t.error();
      resp->set_token(*t);
      return Status::Ok();
    });
  }

  ServerUnaryReactor* RevokeTokens(CallbackServerContext* ctx, const v1::UserRef* req,
                                   v1::Empty*) override {
    return Unary(sh_, ctx, Method::kAdminRevokeTokens, [&](const db::Principal&) -> Status {
      if (Status s = sh_.store.RevokeTokens(req->name()); !s.ok()) return s;
      // Access ends with the tokens: the user's live sessions too (their UDP key is a credential).
      sh_.sessions.EndSessionsOf(req->name(), "access revoked");
      return Status::Ok();
    });
  }

  ServerUnaryReactor* SetDisabled(CallbackServerContext* ctx, const v1::SetDisabledRequest* req,
                                  v1::Empty*) override {
    return Unary(sh_, ctx, Method::kAdminSetDisabled, [&](const db::Principal& p) -> Status {
      if (req->name() == p.name && req->disabled())
        return InvalidArgument("name", "an administrator cannot disable themself");
      if (Status s = sh_.store.SetUserDisabled(req->name(), req->disabled()); !s.ok()) return s;
      if (req->disabled()) sh_.sessions.EndSessionsOf(req->name(), "account disabled");
      return Status::Ok();
    });
  }

  ServerUnaryReactor* ListUsers(CallbackServerContext* ctx, const v1::ListUsersRequest*,
                                v1::ListUsersResponse* resp) override {
    return Unary(sh_, ctx, Method::kAdminListUsers, [&](const db::Principal&) -> Status {
      auto users = sh_.store.ListUsers();
      if (!users.ok()) return users.error();
      for (const db::UserRecord& u : *users) {
        v1::User* o = resp->add_users();
        o->set_name(u.name);
        o->set_role(RoleToProto(u.role));
        o->set_group(u.group);
        o->set_created_us(u.created_us);
        o->set_disabled(u.disabled);
      }
      return Status::Ok();
    });
  }

  ServerUnaryReactor* PutWeightSet(CallbackServerContext* ctx, const v1::WeightSet* req,
                                   v1::Empty*) override {
    return Unary(sh_, ctx, Method::kAdminPutWeightSet, [&](const db::Principal&) -> Status {
      auto w = scoring::WeightSetFromJsonText(req->json());
      if (!w.ok()) return w.error();
      return sh_.store.PutWeightSet(w->name, scoring::WeightSetToJson(*w).dump());
    });
  }

  ServerUnaryReactor* ListWeightSets(CallbackServerContext* ctx, const v1::ListWeightSetsRequest*,
                                     v1::ListWeightSetsResponse* resp) override {
    return Unary(sh_, ctx, Method::kAdminListWeightSets, [&](const db::Principal&) -> Status {
      auto names = sh_.store.ListWeightSets();
      if (!names.ok()) return names.error();
      for (const std::string& n : *names) resp->add_names(n);
      return Status::Ok();
    });
  }

  grpc::ServerWriteReactor<v1::ExportChunk>* Export(CallbackServerContext* ctx,
                                                    const v1::ExportRequest* req) override {
    auto p = Authorize(sh_, ctx, Method::kAdminExport);
    if (!p.ok()) return new Refuse<v1::ExportChunk>(ToGrpcStatus(p.error()));
    const auto format = db::ParseExportFormat(req->format().empty() ? "csv" : req->format());
    if (!format)
      return new Refuse<v1::ExportChunk>(
          ToGrpcStatus(InvalidArgument("format", "csv, jsonl or xapi")));
    db::ExportFilter f;
    if (req->from_us() != 0) f.from_us = req->from_us();
    if (req->to_us() != 0) f.to_us = req->to_us();
    if (!req->trainee().empty()) f.trainee = req->trainee();
    if (req->session() != 0) f.session = static_cast<int64_t>(req->session());
    return new ExportReactor(sh_.store, f, *format);
  }

  ServerUnaryReactor* Backup(CallbackServerContext* ctx, const v1::BackupRequest* req,
                             v1::Empty*) override {
    return Unary(sh_, ctx, Method::kAdminBackup, [&](const db::Principal&) -> Status {
      auto path = BackupPath(sh_.options.backup_dir, req->path());
      if (!path.ok()) return path.error();
      return sh_.store.Backup(path->string());
    });
  }

 private:
  Shared& sh_;
};

}  // namespace

Expected<std::filesystem::path> BackupPath(const std::string& backup_dir, const std::string& name) {
  namespace fs = std::filesystem;
  if (backup_dir.empty())
    return Error{ErrorCode::kFailedPrecondition,
                 "backups are off on this server (start it with --backup-dir DIR)", "path"};
  std::error_code ec;
  const fs::path dir = fs::weakly_canonical(fs::path(backup_dir), ec);
  if (ec) return Error{ErrorCode::kIoError, "cannot resolve the backup directory", "path"};
  // A bare file name in the backup directory, or an absolute path whose folder is that directory.
  fs::path file(name);
  if (file.is_absolute()) {
    if (fs::weakly_canonical(file.parent_path(), ec) != dir || ec)
      return Error{ErrorCode::kPermissionDenied,
                   "backups are written only to the server's backup directory " + dir.string() +
                       "; give a file name",
                   "path"};
    file = file.filename();
  }
  const std::string base = file.string();
  bool plain = !base.empty() && base.size() <= 128 && base.front() != '.';
  for (char c : base)
    plain = plain && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '.' || c == '_' || c == '-');
  if (!plain)
    return InvalidArgument("path",
                           "a file name of letters, digits, '.', '_' and '-' (not starting with "
                           "'.'), written to the server's backup directory");
  fs::create_directories(dir, ec);
  if (ec)
    return Error{ErrorCode::kIoError, "cannot create the backup directory " + dir.string(), "path"};
  const fs::path out = dir / base;
  if (fs::symlink_status(out, ec).type() != fs::file_type::not_found)
    return Error{ErrorCode::kAlreadyExists, "will not overwrite " + out.string(), "path"};
  return out;
}

bool IsLoopbackHost(const std::string& listen) {
  std::string host = listen;
  if (!host.empty() && host.front() == '[') {
    host = host.substr(1, host.find(']') - 1);
  } else if (const auto colon = host.rfind(':');
             colon != std::string::npos && host.find(':') == colon) {
    host = host.substr(0, colon);
  }
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

struct ControlPlane::Impl {
  Shared shared;
  SessionServiceImpl session_service{shared};
  MonitorServiceImpl monitor_service{shared};
  EvaluationServiceImpl evaluation_service{shared};
  AdminServiceImpl admin_service{shared};
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  bool tls = false;
  std::once_flag shutdown_once;
  Impl(db::Store& store, SessionManager& sessions, const ControlPlaneOptions& o)
      : shared{store, sessions, o} {}
};

ControlPlane::ControlPlane(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ControlPlane::~ControlPlane() {
  Shutdown();
}
int ControlPlane::port() const {
  return impl_->port;
}
bool ControlPlane::tls() const {
  return impl_->tls;
}

Expected<std::unique_ptr<ControlPlane>> ControlPlane::Start(db::Store& store,
                                                            SessionManager& sessions,
                                                            const ControlPlaneOptions& options) {
  auto impl = std::make_unique<Impl>(store, sessions, options);
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (options.tls_cert_file.empty() != options.tls_key_file.empty())
    return InvalidArgument("tls", "a certificate and its key are both required");
  if (!options.tls_cert_file.empty()) {
    auto cert = ReadTextFile(options.tls_cert_file, "tls_cert");
    if (!cert.ok()) return cert.error();
    auto key = ReadTextFile(options.tls_key_file, "tls_key");
    if (!key.ok()) return key.error();
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({*key, *cert});
    creds = grpc::SslServerCredentials(ssl);
    impl->tls = true;
  } else {
    if (!IsLoopbackHost(options.listen) && !options.allow_insecure)
      return InvalidArgument("listen",
                             "plaintext gRPC only on loopback; configure a TLS "
                             "certificate (or allow insecure explicitly)");
    creds = grpc::InsecureServerCredentials();
  }
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, creds, &impl->port);
  builder.RegisterService(&impl->session_service);
  builder.RegisterService(&impl->monitor_service);
  builder.RegisterService(&impl->evaluation_service);
  builder.RegisterService(&impl->admin_service);
  impl->server = builder.BuildAndStart();
  if (!impl->server || impl->port == 0)
    return Error{ErrorCode::kUnavailable, "cannot listen on " + options.listen, "listen"};
  return std::unique_ptr<ControlPlane>(new ControlPlane(std::move(impl)));
}

void ControlPlane::Shutdown() {
  std::call_once(impl_->shutdown_once, [this] {
    if (impl_->server) {
      // Streams (monitors, exports) are cancelled at the deadline; unary calls finish first.
      impl_->server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
      impl_->server->Wait();
    }
  });
}

}  // namespace vsurg::server
