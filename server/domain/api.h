// The control plane's rules, once, for every transport: the gRPC services (server/control/) and
// the HTTP API call these and only translate messages and status codes.
//
// Every function takes the caller (a Principal the transport authenticated with Authorize) and
// applies, in this order: the permission matrix (kPermissionDenied), ownership (a trainee touches
// only their own sessions; an evaluator submits only as themself), validation (kInvalidArgument
// naming the field), then the domain call (SessionManager, db::Store, common/scoring). No gRPC,
// protobuf or HTTP type appears here.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/metrics.h"
#include "common/scoring/palpation.h"
#include "db/store.h"
#include "server/domain/auth.h"
#include "server/session/sessions.h"

namespace vsurg::server {

class SceneCatalog;

// What the rules need: the store, the sessions, the scene catalogue, the backup folder.
struct Domain {
  db::Store& store;
  Sessions& sessions;
  SceneCatalog& scenes;
  std::string backup_dir;  // AdminService/Backup writes only here; empty: backups refused
};

// The bearer token of `authorization` ("Bearer <token>"; nullopt: no header) → who calls, when
// their role may call `m` (kUnauthenticated, kPermissionDenied; kUnavailable when the store
// cannot say).
Expected<db::Principal> Authorize(db::Store& store, std::optional<std::string_view> authorization,
                                  Method m);
// Same for a caller already identified (a web session): the matrix only.
Status Permit(const db::Principal& p, Method m);

// --- sessions ---

struct SessionView {
  db::SessionRecord record;                      // with the live state while live
  std::optional<scoring::TrialMetrics> metrics;  // once ended, when recorded
};

// `trainee` empty: the caller (a trainee creating their own session).
Expected<CreatedSession> CreateSession(Domain& d, const db::Principal& p, std::string trainee,
                                       const std::string& scene);
Expected<SessionView> StartSession(Domain& d, const db::Principal& p, uint64_t id);
Expected<SessionView> StopSession(Domain& d, const db::Principal& p, uint64_t id,
                                  const std::string& reason);
Expected<SessionView> GetSession(Domain& d, const db::Principal& p, uint64_t id);
// The trainee's station joins a session prepared for them (by an instructor): the key and UDP
// address go only to that trainee, and only while the session is live.
// with_surface: the station's surface too (a station's first join; not its probes).
Expected<CreatedSession> JoinSession(Domain& d, const db::Principal& p, uint64_t id,
                                     bool with_surface = false);
// Four-handed training (common/sim/guidance.h). An instructor (or an administrator) joins a
// trainee's live session on a channel of their own, in `mode` (kNone: observe); a session that
// ended, one's own, or a mode that does not check (sim::CheckGuideRequest) is refused. Guide
// switches the mode live (the joined instructor only); kNone leaves. GetGuidance: who is in the
// session, for anyone who may read it (its trainee sees who joined and in which mode).
Expected<CreatedSession> JoinAsInstructor(Domain& d, const db::Principal& p, uint64_t id,
                                          const sim::GuideRequest& mode);
Expected<SessionGuidance> GuideSession(Domain& d, const db::Principal& p, uint64_t id,
                                       const sim::GuideRequest& request);
Expected<SessionGuidance> GetGuidance(Domain& d, const db::Principal& p, uint64_t id);
// A live session's surface at rest, for a watcher's 3D view (the monitors' permission).
struct RestSurface {
  std::vector<geometry::Vec3> positions;  // m
  std::vector<int32_t> triangles;         // three vertex indices each
};
Expected<RestSurface> SessionSurface(Domain& d, const db::Principal& p, uint64_t id);
// A trainee lists only their own (`trainee` empty or their name).
Expected<std::vector<SessionView>> ListSessions(Domain& d, const db::Principal& p,
                                                const std::string& trainee, bool live_only);
// Sessions as records: a page of the list with its filters (a trainee sees only their own).
Expected<db::SessionPage> FindSessions(Domain& d, const db::Principal& p, db::SessionQuery q);
// A session's record (server/session/trace_recorder.h, JSON text): so far while it is live, as
// kept once it ended. Whoever may read the session (a trainee their own).
Expected<std::string> SessionTrace(Domain& d, const db::Principal& p, uint64_t id);
// An ended palpation's lumps and marks, from its stored record (the station's summary draws
// them); nullopt while live or for a record without them. The same readers as SessionTrace.
Expected<std::optional<scoring::PalpationOutcome>> SessionPalpation(Domain& d,
                                                                    const db::Principal& p,
                                                                    uint64_t id);
// The ratings of one session, oldest first: all of them for its trainee (without the raters'
// names), instructors and administrators; an evaluator sees only their own, so that ratings
// stay independent (the coil-spring paper's reliability needs raters who did not see each other's).
Expected<std::vector<db::SubmittedRow>> SessionFeedback(Domain& d, const db::Principal& p,
                                                        uint64_t id);
// May `p` watch `session` (0: every live session) at `rate_hz` (0: 30)? Returns the rate.
Expected<double> CheckWatch(Domain& d, const db::Principal& p, uint64_t session, double rate_hz);

// The usable scenes (what Create and the stations resolve) and why the others are not.
struct SceneListing;
Expected<SceneListing> ListScenes(Domain& d, const db::Principal& p);

// --- evaluations ---

struct SubmissionRequest {  // as a transport received it
  std::string idempotency_key, evaluator, evaluator_group, subject_kind, subject;
  std::optional<double> moment_min;
  std::vector<double> scores;  // exactly scoring::kIndexCount
  std::string comment;         // optional, to the trainee
};
// The submission to store: an evaluator submits as themself in their own group; an admin
// imports on an evaluator's behalf (evaluator required).
Expected<db::Submission> PrepareSubmission(const db::Principal& p, const SubmissionRequest& r);
// What waits for this evaluator's scores: ended sessions they have not scored (newest first, at
// most `limit`) and the simulator models (the scenes' models and any model rated before) they
// have not scored; and their own submissions, newest first. Whoever may submit may ask.
struct EvaluationQueue {
  std::vector<db::SessionRecord> sessions;
  std::vector<std::string> models;
  std::vector<db::SubmittedRow> submitted;
};
Expected<EvaluationQueue> ListOwnEvaluations(Domain& d, const db::Principal& p, int limit);
// The weighted report (the coil-spring paper eqs. 9–11) of one subject, or the comparison of up to
// 32, as JSON text; recorded in the store with the weights it used.
Expected<std::string> Report(Domain& d, const db::Principal& p, const std::string& subject_kind,
                             const std::vector<std::string>& subjects,
                             const std::string& weight_set);
// The subjects of `kind` (session, trainee, model) that anyone has rated, by name.
Expected<std::vector<std::string>> RatedSubjects(Domain& d, const db::Principal& p,
                                                 const std::string& kind);
// The training-effect cells (trainee group × moment) as JSON text.
Expected<std::string> TrainingEffect(Domain& d, const db::Principal& p,
                                     const std::string& weight_set);

// --- administration ---

Expected<db::UserRecord> CreateUser(Domain& d, const db::Principal& p, const std::string& name,
                                    std::optional<db::Role> role, const std::string& group);
Expected<std::string> IssueToken(Domain& d, const db::Principal& p, const std::string& user,
                                 const std::string& label);
// Access ends with the tokens: the user's live sessions too (their UDP key is a credential).
Status RevokeTokens(Domain& d, const db::Principal& p, const std::string& user);
Status SetDisabled(Domain& d, const db::Principal& p, const std::string& user, bool disabled);
Expected<std::vector<db::UserRecord>> ListUsers(Domain& d, const db::Principal& p);
Status PutWeightSet(Domain& d, const db::Principal& p, const std::string& json);
Expected<std::vector<std::string>> ListWeightSets(Domain& d, const db::Principal& p);
// One weight set as JSON text (`name` empty: the coil-spring paper's published weights, built in).
Expected<std::string> GetWeightSet(Domain& d, const db::Principal& p, const std::string& name);
Status Backup(Domain& d, const db::Principal& p, const std::string& name);

struct ExportPlan {
  db::ExportFilter filter;
  db::ExportFormat format = db::ExportFormat::kCsv;
};
// An export's filter and format from a request (0 and "" mean "not given"; format "" is csv);
// the transport then streams db::Store::Export.
Expected<ExportPlan> PlanExport(const db::Principal& p, const std::string& format, int64_t from_us,
                                int64_t to_us, const std::string& trainee, uint64_t session);

// Where a backup may write `name`: a plain file name (or an absolute path whose folder is
// `backup_dir`) that does not exist yet, inside `backup_dir` (created when missing).
Expected<std::filesystem::path> BackupPath(const std::string& backup_dir, const std::string& name);

}  // namespace vsurg::server
