#include "server/domain/api.h"

#include <set>

#include <nlohmann/json.hpp>

#include "common/scoring/evaluation.h"
#include "common/scoring/report_json.h"
#include "server/domain/scene_catalog.h"
#include "server/session/trace_recorder.h"

namespace vsurg::server {
namespace {

Error Denied(const std::string& what) {
  return Error{ErrorCode::kPermissionDenied, what, ""};
}

// A trainee may touch only their own sessions.
Status OwnSession(const db::Principal& p, const db::SessionRecord& r) {
  if (p.role == db::Role::kTrainee && r.trainee != p.name)
    return Denied("session " + std::to_string(r.id) + " belongs to another trainee");
  return Status::Ok();
}

// The caller may call `m` and the session is theirs to touch.
Status MayTouch(Domain& d, const db::Principal& p, Method m, uint64_t id) {
  if (Status s = Permit(p, m); !s.ok()) return s;
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  return OwnSession(p, *r);
}

// The record with, once it has left the live states, the scoring loop's metrics.
Expected<SessionView> View(Domain& d, db::SessionRecord record) {
  SessionView v{std::move(record), std::nullopt};
  if (IsLive(v.record.state)) return v;
  auto m = d.store.GetTrialMetrics(v.record.id);
  if (!m.ok()) return m.error();
  v.metrics = *m;
  return v;
}

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

}  // namespace

Expected<db::Principal> Authorize(db::Store& store, std::optional<std::string_view> authorization,
                                  Method m) {
  if (!authorization)
    return Error{ErrorCode::kUnauthenticated, "missing 'authorization: Bearer <token>' metadata",
                 ""};
  const auto token = BearerToken(*authorization);
  if (!token)
    return Error{ErrorCode::kUnauthenticated, "malformed authorization: expected 'Bearer <token>'",
                 ""};
  auto p = store.Authenticate(*token);
  if (!p.ok()) {
    if (p.error().code == ErrorCode::kUnauthenticated) return p.error();
    return Error{ErrorCode::kUnavailable, "cannot check credentials: " + p.error().message, ""};
  }
  if (Status s = Permit(*p, m); !s.ok()) return s.error();
  return p;
}

Status Permit(const db::Principal& p, Method m) {
  if (!RoleMay(p.role, m))
    return Denied(std::string("role ") + db::RoleName(p.role) + " may not call " + MethodName(m));
  return Status::Ok();
}

// --- sessions ---

Expected<CreatedSession> CreateSession(Domain& d, const db::Principal& p, std::string trainee,
                                       const std::string& scene) {
  if (Status s = Permit(p, Method::kSessionCreate); !s.ok()) return s.error();
  if (trainee.empty()) {
    if (p.role != db::Role::kTrainee)
      return InvalidArgument("trainee", "required (the trainee the session is for)");
    trainee = p.name;
  }
  if (p.role == db::Role::kTrainee && trainee != p.name)
    return Denied("a trainee creates sessions only for themself");
  return d.sessions.Create(trainee, scene);
}

Expected<SessionView> StartSession(Domain& d, const db::Principal& p, uint64_t id) {
  if (Status s = MayTouch(d, p, Method::kSessionStart, id); !s.ok()) return s.error();
  auto r = d.sessions.Start(id);
  if (!r.ok()) return r.error();
  return SessionView{*r, std::nullopt};
}

Expected<SessionView> StopSession(Domain& d, const db::Principal& p, uint64_t id,
                                  const std::string& reason) {
  if (Status s = MayTouch(d, p, Method::kSessionStop, id); !s.ok()) return s.error();
  if (reason.size() > 256) return InvalidArgument("reason", "at most 256 characters");
  auto r = d.sessions.Stop(id, reason);
  if (!r.ok()) return r.error();
  return View(d, *r);
}

Expected<SessionView> GetSession(Domain& d, const db::Principal& p, uint64_t id) {
  if (Status s = Permit(p, Method::kSessionGet); !s.ok()) return s.error();
  auto r = d.sessions.Get(id);
  if (!r.ok()) return r.error();
  if (Status s = OwnSession(p, *r); !s.ok()) return s.error();
  return View(d, *r);
}

Expected<CreatedSession> JoinSession(Domain& d, const db::Principal& p, uint64_t id,
                                     bool with_surface) {
  if (Status s = Permit(p, Method::kSessionJoin); !s.ok()) return s.error();
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  if (r->trainee != p.name)  // never another trainee's key, whatever the role
    return Denied("session " + std::to_string(id) + " belongs to another trainee");
  return d.sessions.Join(id, with_surface);
}

Expected<CreatedSession> JoinAsInstructor(Domain& d, const db::Principal& p, uint64_t id,
                                          const sim::GuideRequest& mode) {
  if (Status s = Permit(p, Method::kSessionJoinInstructor); !s.ok()) return s.error();
  sim::GuideRequest start = mode;
  if (start.mode == sim::GuideMode::kNone) start.mode = sim::GuideMode::kObserve;
  if (Status s = sim::CheckGuideRequest(start); !s.ok()) return s.error();
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  if (r->trainee == p.name) return Denied("an instructor joins another's session, not their own");
  if (!IsLive(r->state))
    return Error{ErrorCode::kFailedPrecondition,
                 "session " + std::to_string(id) + " is " + SessionStateName(r->state) +
                     ": only a live session is joined",
                 "id"};
  auto joined = d.sessions.JoinInstructor(id, p.name);
  if (!joined.ok()) return joined.error();
  if (auto g = d.sessions.Guide(id, p.name, start); !g.ok()) {
    (void)d.sessions.LeaveInstructor(id, p.name);
    return g.error();
  }
  return joined;
}

Expected<SessionGuidance> GuideSession(Domain& d, const db::Principal& p, uint64_t id,
                                       const sim::GuideRequest& request) {
  if (Status s = Permit(p, Method::kSessionGuide); !s.ok()) return s.error();
  if (Status s = sim::CheckGuideRequest(request); !s.ok()) return s.error();
  if (request.mode == sim::GuideMode::kNone) {
    if (Status s = d.sessions.LeaveInstructor(id, p.name); !s.ok()) return s.error();
    return d.sessions.Guidance(id);
  }
  return d.sessions.Guide(id, p.name, request);
}

Expected<SessionGuidance> GetGuidance(Domain& d, const db::Principal& p, uint64_t id) {
  if (Status s = MayTouch(d, p, Method::kSessionGet, id); !s.ok()) return s.error();
  return d.sessions.Guidance(id);
}

Expected<RestSurface> SessionSurface(Domain& d, const db::Principal& p, uint64_t id) {
  if (Status s = Permit(p, Method::kMonitorWatch); !s.ok()) return s.error();
  RestSurface out;
  if (Status s = d.sessions.RestSurface(id, out.positions, out.triangles); !s.ok())
    return s.error();
  return out;
}

Expected<std::vector<SessionView>> ListSessions(Domain& d, const db::Principal& p,
                                                const std::string& trainee, bool live_only) {
  if (Status s = Permit(p, Method::kSessionList); !s.ok()) return s.error();
  std::optional<std::string> who;
  if (!trainee.empty()) who = trainee;
  if (p.role == db::Role::kTrainee) {
    if (who && *who != p.name) return Denied("a trainee lists only their sessions");
    who = p.name;
  }
  auto list = d.store.ListSessions(who);
  if (!list.ok()) return list.error();
  std::vector<SessionView> out;
  for (db::SessionRecord& r : *list) {
    if (d.sessions.IsLive(static_cast<uint64_t>(r.id))) {
      auto live = d.sessions.Get(static_cast<uint64_t>(r.id));
      if (live.ok()) r = *live;
    }
    if (live_only && !IsLive(r.state)) continue;
    auto v = View(d, std::move(r));
    if (!v.ok()) return v.error();
    out.push_back(std::move(v).value());
  }
  return out;
}

Expected<std::vector<std::string>> RatedSubjects(Domain& d, const db::Principal& p,
                                                 const std::string& kind) {
  if (Status s = Permit(p, Method::kEvaluationReport); !s.ok()) return s.error();
  const auto k = db::ParseSubjectKind(kind);
  if (!k)
    return InvalidArgument("kind",
                           "unknown subject kind '" + kind + "' (session, trainee or model)");
  return d.store.ListRatedSubjects(*k);
}

Expected<db::SessionPage> FindSessions(Domain& d, const db::Principal& p, db::SessionQuery q) {
  if (Status s = Permit(p, Method::kSessionList); !s.ok()) return s.error();
  if (p.role == db::Role::kTrainee) {
    if (q.trainee && *q.trainee != p.name) return Denied("a trainee lists only their sessions");
    q.trainee = p.name;
  }
  return d.store.FindSessions(q);
}

Expected<std::string> SessionTrace(Domain& d, const db::Principal& p, uint64_t id) {
  if (Status s = Permit(p, Method::kSessionGet); !s.ok()) return s.error();
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  if (Status s = OwnSession(p, *r); !s.ok()) return s.error();
  if (IsLive(r->state)) {
    auto live = d.sessions.Trace(id);
    if (live.ok() || live.error().code != ErrorCode::kNotFound) return live;
    // It ended between the two reads: the store has it now.
  }
  return d.store.GetSessionTrace(static_cast<int64_t>(id));
}

Expected<std::optional<scoring::PalpationOutcome>> SessionPalpation(Domain& d,
                                                                    const db::Principal& p,
                                                                    uint64_t id) {
  if (Status s = Permit(p, Method::kSessionGet); !s.ok()) return s.error();
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  if (Status s = OwnSession(p, *r); !s.ok()) return s.error();
  if (IsLive(r->state)) return std::optional<scoring::PalpationOutcome>();
  auto trace = d.store.GetSessionTrace(static_cast<int64_t>(id));
  if (!trace.ok()) {
    if (trace.error().code == ErrorCode::kNotFound)
      return std::optional<scoring::PalpationOutcome>();
    return trace.error();
  }
  return TraceRecorder::PalpationOf(*trace);
}

Expected<std::vector<db::SubmittedRow>> SessionFeedback(Domain& d, const db::Principal& p,
                                                        uint64_t id) {
  if (Status s = Permit(p, Method::kSessionGet); !s.ok()) return s.error();
  auto r = d.store.GetSession(static_cast<int64_t>(id));
  if (!r.ok()) return r.error();
  if (Status s = OwnSession(p, *r); !s.ok()) return s.error();
  auto rows = d.store.ListSubmissionsOn(db::SubjectKind::kSession, std::to_string(id));
  if (!rows.ok()) return rows;
  std::vector<db::SubmittedRow> out;
  for (db::SubmittedRow& row : *rows) {
    if (p.role == db::Role::kEvaluator && row.evaluator != p.name) continue;
    if (p.role == db::Role::kTrainee) row.evaluator.clear();
    out.push_back(std::move(row));
  }
  return out;
}

Expected<double> CheckWatch(Domain& d, const db::Principal& p, uint64_t session, double rate_hz) {
  if (Status s = Permit(p, Method::kMonitorWatch); !s.ok()) return s.error();
  const double hz = rate_hz == 0 ? 30.0 : rate_hz;
  if (!(hz >= 1 && hz <= 60)) return InvalidArgument("rate_hz", "must be within 1..60");
  if (session != 0 && !d.sessions.IsLive(session)) {
    auto r = d.store.GetSession(static_cast<int64_t>(session));
    if (!r.ok()) return r.error();
    return Error{
        ErrorCode::kFailedPrecondition,
        "session " + std::to_string(session) + " is " + SessionStateName(r->state) + ", not live",
        "session_id"};
  }
  return hz;
}

Expected<SceneListing> ListScenes(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kSessionListScenes); !s.ok()) return s.error();
  return d.scenes.List();
}

// --- evaluations ---

Expected<db::Submission> PrepareSubmission(const db::Principal& p, const SubmissionRequest& r) {
  if (Status s = Permit(p, Method::kEvaluationSubmit); !s.ok()) return s.error();
  db::Submission s;
  s.idempotency_key = r.idempotency_key;
  s.evaluator = r.evaluator;
  s.evaluator_group = r.evaluator_group;
  s.subject = r.subject;
  s.submitted_by = p.name;
  s.moment_min = r.moment_min;
  s.comment = r.comment;
  if (p.role == db::Role::kEvaluator) {
    // Evaluators submit as themselves, in their own group.
    if (s.evaluator.empty()) s.evaluator = p.name;
    if (s.evaluator_group.empty()) s.evaluator_group = p.group;
    if (s.evaluator != p.name) return Denied("an evaluator submits only their own scores");
  } else if (s.evaluator.empty()) {
    return InvalidArgument("evaluator", "required when importing on an evaluator's behalf");
  }
  const auto kind = db::ParseSubjectKind(r.subject_kind);
  if (!kind)
    return InvalidArgument("subject_kind", "unknown subject kind '" + r.subject_kind +
                                               "' (session, trainee or model)");
  if (r.scores.size() != static_cast<size_t>(scoring::kIndexCount))
    return InvalidArgument(
        "scores", "exactly 9 index scores are required, got " + std::to_string(r.scores.size()));
  s.subject_kind = *kind;
  for (int j = 0; j < scoring::kIndexCount; ++j) s.scores[j] = r.scores[j];
  return s;  // the store validates the rest (0–10, group, subject) inside its transaction
}

Expected<EvaluationQueue> ListOwnEvaluations(Domain& d, const db::Principal& p, int limit) {
  if (Status s = Permit(p, Method::kEvaluationSubmit); !s.ok()) return s.error();
  if (limit < 1 || limit > 1000) return InvalidArgument("limit", "must be within 1..1000");
  EvaluationQueue q;
  auto mine = d.store.ListSubmissionsBy(p.name, 100000);
  if (!mine.ok()) return mine.error();
  std::set<std::pair<db::SubjectKind, std::string>> done;
  for (const db::SubmittedRow& r : *mine) done.insert({r.subject_kind, r.subject});
  auto sessions = d.store.ListSessions(std::nullopt);
  if (!sessions.ok()) return sessions.error();
  for (auto it = sessions->rbegin(); it != sessions->rend(); ++it) {
    if (it->state != SessionState::kEnded) continue;
    if (done.count({db::SubjectKind::kSession, std::to_string(it->id)})) continue;
    q.sessions.push_back(*it);
    if (static_cast<int>(q.sessions.size()) == limit) break;
  }
  std::set<std::string> models;
  if (auto listing = d.scenes.List(); listing.ok())
    for (const SceneInfo& s : listing->scenes) models.insert(s.model);
  auto rated = d.store.ListRatedSubjects(db::SubjectKind::kModel);
  if (!rated.ok()) return rated.error();
  models.insert(rated->begin(), rated->end());
  for (const std::string& m : models)
    if (!done.count({db::SubjectKind::kModel, m})) q.models.push_back(m);
  mine->resize(std::min<size_t>(mine->size(), static_cast<size_t>(limit)));
  q.submitted = std::move(*mine);
  return q;
}

Expected<std::string> Report(Domain& d, const db::Principal& p, const std::string& subject_kind,
                             const std::vector<std::string>& subjects,
                             const std::string& weight_set) {
  if (Status s = Permit(p, Method::kEvaluationReport); !s.ok()) return s.error();
  const auto kind = db::ParseSubjectKind(subject_kind);
  if (!kind) return InvalidArgument("subject_kind", "session, trainee or model");
  if (subjects.empty() || subjects.size() > 32)
    return InvalidArgument("subjects", "1 to 32 subjects");
  auto weights = LoadWeights(d.store, weight_set);
  if (!weights.ok()) return weights.error();
  std::vector<scoring::SubjectRatings> rated;
  for (const std::string& subject : subjects) {
    auto rows = d.store.LoadRatings(*kind, subject);
    if (!rows.ok()) return rows.error();
    if (rows->empty())
      return Error{ErrorCode::kNotFound, "no evaluations of " + subject_kind + " '" + subject + "'",
                   "subjects"};
    auto ratings = ToRatings(*rows);
    if (!ratings.ok()) return ratings.error();
    rated.push_back({subject, std::move(ratings).value()});
  }
  nlohmann::json j;
  if (rated.size() == 1) {
    auto rep = scoring::Evaluate(rated[0].ratings, *weights);
    if (!rep.ok()) return rep.error();
    j = scoring::ReportToJson(*rep);
    j["subject"] = rated[0].subject;
  } else {
    auto cmp = scoring::Compare(rated, *weights);
    if (!cmp.ok()) return cmp.error();
    j = scoring::ComparisonToJson(*cmp, subjects);
  }
  j["subject_kind"] = subject_kind;
  std::string text = j.dump();
  // Recorded with the weights it used (a report can always be explained later).
  if (Status s = d.store.RecordReport(subject_kind, subjects[0],
                                      scoring::WeightSetToJson(*weights).dump(), text);
      !s.ok())
    return s.error();
  return text;
}

Expected<std::string> TrainingEffect(Domain& d, const db::Principal& p,
                                     const std::string& weight_set) {
  if (Status s = Permit(p, Method::kEvaluationTrainingEffect); !s.ok()) return s.error();
  auto weights = LoadWeights(d.store, weight_set);
  if (!weights.ok()) return weights.error();
  auto rows = d.store.LoadTrainingRows();
  if (!rows.ok()) return rows.error();
  // Each evaluator's score of a trainee is their comprehensive score (eq. 11 weights).
  std::vector<scoring::TrainingScore> scores;
  for (const db::TrainingRow& t : *rows) {
    double n = 0;
    for (int j = 0; j < scoring::kIndexCount; ++j) n += weights->index[j] * t.scores[j];
    scores.push_back({t.trainee, t.trainee_group, t.moment_min, t.evaluator, n});
  }
  auto cells = scoring::TrainingEffect(scores);
  if (!cells.ok()) return cells.error();
  return scoring::TrainingToJson(*cells).dump();
}

// --- administration ---

Expected<db::UserRecord> CreateUser(Domain& d, const db::Principal& p, const std::string& name,
                                    std::optional<db::Role> role, const std::string& group) {
  if (Status s = Permit(p, Method::kAdminCreateUser); !s.ok()) return s.error();
  if (!role) return InvalidArgument("role", "trainee, instructor, evaluator or admin");
  return d.store.CreateUser(name, *role, group);
}

Expected<std::string> IssueToken(Domain& d, const db::Principal& p, const std::string& user,
                                 const std::string& label) {
  if (Status s = Permit(p, Method::kAdminIssueToken); !s.ok()) return s.error();
  return d.store.IssueToken(user, label);
}

Status RevokeTokens(Domain& d, const db::Principal& p, const std::string& user) {
  if (Status s = Permit(p, Method::kAdminRevokeTokens); !s.ok()) return s;
  if (Status s = d.store.RevokeTokens(user); !s.ok()) return s;
  d.sessions.EndSessionsOf(user, "access revoked");
  return Status::Ok();
}

Status SetDisabled(Domain& d, const db::Principal& p, const std::string& user, bool disabled) {
  if (Status s = Permit(p, Method::kAdminSetDisabled); !s.ok()) return s;
  if (user == p.name && disabled)
    return InvalidArgument("name", "an administrator cannot disable themself");
  if (Status s = d.store.SetUserDisabled(user, disabled); !s.ok()) return s;
  if (disabled) d.sessions.EndSessionsOf(user, "account disabled");
  return Status::Ok();
}

Expected<std::vector<db::UserRecord>> ListUsers(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kAdminListUsers); !s.ok()) return s.error();
  return d.store.ListUsers();
}

Status PutWeightSet(Domain& d, const db::Principal& p, const std::string& json) {
  if (Status s = Permit(p, Method::kAdminPutWeightSet); !s.ok()) return s;
  auto w = scoring::WeightSetFromJsonText(json);
  if (!w.ok()) return w.error();
  return d.store.PutWeightSet(w->name, scoring::WeightSetToJson(*w).dump());
}

Expected<std::vector<std::string>> ListWeightSets(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kAdminListWeightSets); !s.ok()) return s.error();
  return d.store.ListWeightSets();
}

Expected<std::string> GetWeightSet(Domain& d, const db::Principal& p, const std::string& name) {
  if (Status s = Permit(p, Method::kAdminListWeightSets); !s.ok()) return s.error();
  auto w = LoadWeights(d.store, name);
  if (!w.ok()) return w.error();
  return scoring::WeightSetToJson(*w).dump();
}

Status Backup(Domain& d, const db::Principal& p, const std::string& name) {
  if (Status s = Permit(p, Method::kAdminBackup); !s.ok()) return s;
  auto path = BackupPath(d.backup_dir, name);
  if (!path.ok()) return path.error();
  return d.store.Backup(path->string());
}

Expected<ExportPlan> PlanExport(const db::Principal& p, const std::string& format, int64_t from_us,
                                int64_t to_us, const std::string& trainee, uint64_t session) {
  if (Status s = Permit(p, Method::kAdminExport); !s.ok()) return s.error();
  const auto f = db::ParseExportFormat(format.empty() ? "csv" : format);
  if (!f) return InvalidArgument("format", "csv, jsonl or xapi");
  ExportPlan plan;
  plan.format = *f;
  if (from_us != 0) plan.filter.from_us = from_us;
  if (to_us != 0) plan.filter.to_us = to_us;
  if (!trainee.empty()) plan.filter.trainee = trainee;
  if (session != 0) plan.filter.session = static_cast<int64_t>(session);
  return plan;
}

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

}  // namespace vsurg::server
