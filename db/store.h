// The evaluation store (DESIGN.md "Storage"): users and token hashes, trainees and evaluators
// with their groups, scenes, sessions, trial metrics, evaluations, training moments, weight sets
// and recorded reports. Knows nothing of physics or of the network.
//
// Two backends behind one interface (db/connection.h), chosen by the location: an SQLite file
// (the embedded default) or a `postgresql://` URI (a shared store that several control replicas
// write at once). Same schema, same migrations, same contract; the test suite runs on both.
//
// Design notes
//  1. SQLite: one file, WAL, synchronous=FULL, foreign keys on, busy timeout. PostgreSQL:
//     synchronous_commit on, a lock timeout. Schema changes are forward-only migrations
//     numbered by a schema version (db/migrations.cpp); a database newer than this binary is
//     refused, never "downgraded".
//  2. One writer thread owns this process's only read-write connection. Every write is a job;
//     the writer takes all queued jobs (up to max_batch), runs them inside one transaction,
//     each inside its own SAVEPOINT (a failing job rolls back alone: nothing partly written),
//     then COMMITs once — group commit: one fsync for the whole batch. A job's completion is
//     reported only after that COMMIT returned, so an acknowledged write is durable.
//     Several processes on one PostgreSQL each have their writer; unique constraints, not the
//     writer, keep their jobs from contradicting each other (a lost race is kAlreadyExists).
//     A lost PostgreSQL connection fails the batch with kUnavailable (nothing acknowledged) and
//     the next batch reconnects. A lease renewal (BeatNode) is one UPDATE and needs no
//     transaction around it: the writer runs it in autocommit ahead of the batch, one round
//     trip to a shared store instead of five.
//  3. Reads use a small pool of read-only connections (they never block the writer and see
//     the last committed state).
//  4. Only prepared statements with bound values; no SQL text is built from input.
//  5. Tokens are 256-bit random secrets; only their SHA-256 is stored. (A slow password hash
//     buys nothing for secrets this long, and authentication stays a single indexed lookup.)
//  6. Times are integers, microseconds since the Unix epoch, UTC; exports print ISO-8601.
//  7. Fencing (a site's nodes): a node name is held by one process at a time (AcquireNode
//     refuses while another instance's lease in the row is unexpired); each acquisition is a
//     new epoch. A session row records the epoch of the process that created it, and every
//     write to it names that epoch: the write is refused (kFailedPrecondition) unless the node
//     is up at that epoch. A session that has left the live states never changes again,
//     whoever asks: an aborted session cannot be brought back by a node that comes back. The
//     node's row is locked first, then the session's, the order MarkNodeDown and AcquireNode
//     take too, so a fenced write and a node's fall never interleave. On PostgreSQL session
//     writes share the row lock (FOR KEY SHARE) and the fall takes it alone (FOR UPDATE); a
//     lease renewal (BeatNode) waits for neither session writes nor the node's long
//     transactions.
//  8. Placement (server/cluster): a control replica reserves its choice of node in the store
//     before it asks the node (ReservePlacement, serialised across replicas: PostgreSQL's
//     transaction-scoped advisory lock, SQLite's write lock), and the node's CreateSession (or
//     MoveSession) deletes the reservation in the transaction that writes the session's row.
//     A load read at any moment counts every placement once, whichever replica made it and
//     whether or not its node has answered yet. The reservation runs on a connection of its own
//     (never queued behind the writer's batch), and on PostgreSQL its commit does not wait for
//     the WAL's flush: a reservation is a transient count that expires, never a record.
//
// Thread safety: every public member may be called from any thread.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/core/session_state.h"
#include "common/core/time.h"
#include "common/scoring/metrics.h"
#include "common/scoring/vocabulary.h"
#include "db/connection.h"
#include "db/vocabulary.h"

namespace vsurg::db {

struct UserRecord {
  int64_t id = 0;
  std::string name;
  Role role = Role::kTrainee;
  std::string group;  // trainee group, or evaluator group (intern, associate_chief, chief)
  int64_t created_us = 0;
  bool disabled = false;
};

struct Principal {  // who a token belongs to
  int64_t user_id = 0;
  std::string name;
  Role role = Role::kTrainee;
  std::string group;
};

struct SessionRecord {
  int64_t id = 0;
  std::string trainee;
  std::string scene;
  SessionState state = SessionState::kCreated;  // stored by name
  int64_t created_us = 0, started_us = 0, ended_us = 0;
  std::string end_reason;
  std::string node;  // the simulation node it runs on; "" in the all-in-one server
};

// A simulation node as its last heartbeat described it (DESIGN.md "Beyond one machine").
struct NodeRecord {
  std::string name;          // unique in the site (the StatefulSet's pod name)
  std::string grpc_address;  // its internal API, host:port
  std::string udp_host;      // what stations are told to send to
  int udp_port = 0;
  int capacity = 0;       // live sessions it takes (configuration, measured in docs/SCALING.md)
  int sessions = 0;       // live sessions it reported
  double cpu = 0;         // its process's CPU use over the last heartbeat period, in cores
  bool draining = false;  // takes no new sessions
  bool down = false;      // missed its heartbeats; its sessions were aborted
  int64_t started_us = 0, heartbeat_us = 0;
  // The lease (design note 7): the process that holds the name (random, per process) and the
  // number of its acquisition. Every session write of that process carries the epoch.
  std::string instance;
  int64_t epoch = 0;
};

// Who may write a session's row: the node process that created it, while its lease holds. The
// all-in-one server writes with the empty fence (node "", epoch 0).
struct SessionFence {
  std::string node;
  int64_t epoch = 0;
};

// A node name acquired (AcquireNode): its new epoch, and how many live sessions an earlier
// holder of the name had left (aborted in the same transaction).
struct NodeLease {
  int64_t epoch = 0;
  int aborted = 0;
};

struct Submission {
  std::string idempotency_key;  // the client's; a retry with the same key is not a second row
  std::string evaluator;
  std::string evaluator_group;  // intern, associate_chief, chief
  SubjectKind subject_kind = SubjectKind::kSession;
  std::string subject;               // session id, trainee name, or simulator model name
  std::optional<double> moment_min;  // training moment (trainee subjects), minutes
  std::array<double, scoring::kIndexCount> scores{};
  std::string submitted_by;  // the user who sent it (the evaluator, or an admin importing)
  std::string comment;       // the evaluator's words to the trainee (at most kMaxComment bytes)
};
constexpr size_t kMaxComment = 4000;
// A training moment is the training time so far: at most this many minutes (some 1,700 hours).
constexpr double kMaxMomentMin = 100000;

struct SubmitResult {
  int64_t submission_id = 0;
  int64_t submitted_us = 0;
  bool duplicate = false;  // the idempotency key was seen: this is the original's result
};

struct RatingRow {  // one evaluator's nine scores on one subject
  std::string evaluator;
  std::string evaluator_group;
  std::optional<double> moment_min;
  std::array<double, scoring::kIndexCount> scores{};
};

struct TrainingRow {  // one evaluator's scores of a trainee at a training moment
  std::string trainee;
  std::string trainee_group;
  double moment_min = 0;
  std::string evaluator;
  std::array<double, scoring::kIndexCount> scores{};
};

struct SubmittedRow {  // one of an evaluator's own submissions
  int64_t id = 0;
  SubjectKind subject_kind = SubjectKind::kSession;
  std::string subject;
  std::optional<double> moment_min;
  int64_t submitted_us = 0;
  std::array<double, scoring::kIndexCount> scores{};
  std::string comment;
  std::string evaluator, evaluator_group;  // filled by ListSubmissionsOn
};

// Ended sessions as records: a page of the list with filters (each one optional).
struct SessionQuery {
  std::optional<std::string> trainee, scene;
  std::optional<std::string> search;      // a part of the trainee's or the scene's name
  std::optional<int64_t> from_us, to_us;  // created in [from, to)
  std::optional<double> min_score, max_score;
  bool ended_only = true;      // sessions that left the live states
  int limit = 25, offset = 0;  // newest first
};
struct SessionRow {
  SessionRecord record;
  std::optional<double> score;  // the trial's, when recorded
  bool completed = false;
  bool has_trace = false;
};
struct SessionPage {
  std::vector<SessionRow> rows;
  int64_t total = 0;  // rows matching the filters, over every page
};

// The training programme (server/domain/training.h decides; the store keeps). An exercise's
// targets, rule and benchmark are its spec, JSON text the domain writes and reads.
struct ExerciseRecord {
  int64_t id = 0, course_id = 0;
  int position = 0;  // 1, 2, … in the course's order
  std::string title, scene, spec_json;
};
struct CourseRecord {
  int64_t id = 0;
  std::string name, description, owner;  // owner: the instructor (or admin) who made it
  int64_t created_us = 0;
  std::vector<ExerciseRecord> exercises;  // by position
};
struct CohortRecord {
  int64_t id = 0;
  std::string name, instructor;
  int64_t created_us = 0;
  std::vector<std::string> members;  // trainee names, sorted
};
struct EnrolmentRecord {
  int64_t id = 0, course_id = 0;
  std::optional<int64_t> cohort_id;  // a cohort's enrolment, or
  std::string trainee;               // one trainee's ("" for a cohort's)
  int64_t starts_us = 0;
  std::optional<int64_t> ends_us;
  int64_t created_us = 0;
};
// One recorded trial: a session that ended with trial metrics (those a proficiency target can
// name, scoring::ProficiencyMetrics; the rest are not read).
struct AttemptRow {
  int64_t session_id = 0;
  std::string trainee;
  int64_t exercise_id = 0;  // 0: not an attempt at an exercise
  int64_t ended_us = 0;
  scoring::TrialMetrics metrics;
};

// Trainee names from `first` to `last`, both included, in the names' order.
struct NameRange {
  std::string first, last;
};

struct ExportFilter {
  std::optional<int64_t> from_us = std::nullopt;  // submitted in [from, to)
  std::optional<int64_t> to_us = std::nullopt;
  std::optional<std::string> trainee = std::nullopt;  // trainee subjects, and their sessions
  std::optional<int64_t> session = std::nullopt;
};

struct StoreOptions {
  std::string path = "";     // an SQLite file, or a postgresql:// URI (db/connection.h)
  int max_batch = 1024;      // jobs per group commit
  int read_connections = 4;  // pool size
  int busy_timeout_ms = 5000;
};

struct StoreStats {
  uint64_t commits = 0;
  uint64_t jobs = 0;
  uint64_t failed_jobs = 0;     // refused or failed jobs (a stale epoch, a constraint, the below)
  uint64_t failed_commits = 0;  // a BEGIN or COMMIT that failed: the store itself (gone, full)
  // Each group commit's time from BEGIN to COMMIT done (s), as counts per bucket: bucket b holds
  // the commits at most kCommitBounds[b] and above the bound before it; the last, above all.
  static constexpr std::array<double, 10> kCommitBounds{0.0005, 0.001, 0.002, 0.005, 0.01,
                                                        0.02,   0.05,  0.1,   0.25,  1};
  std::array<uint64_t, kCommitBounds.size() + 1> commit_buckets{};
  double commit_seconds = 0;        // their sum
  uint64_t queued = 0;              // jobs waiting for the writer when read
  uint64_t writer_round_trips = 0;  // requests the writer sent its server (PostgreSQL; SQLite 0)
};

class Store {
 public:
  // Opens or creates the file and migrates it to the current schema: the server's open, the
  // only writer.
  static Expected<std::unique_ptr<Store>> Open(const StoreOptions& options);
  // Opens an existing file for reading only: never creates it (a mistyped path is kNotFound),
  // never migrates it (a file at another schema version is kFailedPrecondition), starts no
  // writer; every write fails with kFailedPrecondition. Safe beside a live server (WAL readers
  // never block its writer). For offline exports and inspection.
  static Expected<std::unique_ptr<Store>> OpenReadOnly(const std::string& path);
  bool read_only() const;
  ~Store();  // finishes the queued writes, then closes
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  static int SchemaVersion();  // the user_version this binary migrates to

  // --- Writes (through the writer thread; durable when they return or call back) ---
  // A write job runs on the writer thread inside its own savepoint. Its Status decides whether
  // the savepoint is kept.
  using Job = std::function<Status(Connection&)>;
  Status Write(Job job);
  void WriteAsync(Job job, std::function<void(Status)> done);

  Expected<UserRecord> CreateUser(const std::string& name, Role role, const std::string& group);
  Status SetUserDisabled(const std::string& name, bool disabled);
  // A new token for the user; the plain token is returned once and never stored.
  Expected<std::string> IssueToken(const std::string& user, const std::string& label);
  Status RevokeTokens(const std::string& user);
  // A sign-in through the site's identity provider (OpenID Connect): the user is created with the
  // provider's role when unknown; a disabled account, or one whose role here differs from the
  // provider's, is refused (kPermissionDenied, naming it). Returns a new token for the web session
  // (label kFederatedLabel, never shown to anyone); this user's earlier such tokens older than
  // `session_ttl_s` (their web sessions have expired) are revoked in the same transaction.
  Expected<std::string> SignInFederated(const std::string& user, Role role, double session_ttl_s);
  static constexpr const char* kFederatedLabel = "oidc-web";
  // `vsurg-admin init`: creates the first admin and a token; fails when any admin exists.
  Expected<std::string> InitAdmin(const std::string& name);

  // A new live session of `fence.node` (design note 7: refused unless that node is up at
  // `fence.epoch`); the reservation `placement` (ReservePlacement) is replaced by it.
  Expected<SessionRecord> CreateSession(const std::string& trainee, const std::string& scene,
                                        const SessionFence& fence = {},
                                        const std::string& placement = "");
  // A live session's next state, written by the process `fence` names. kNotFound: no such
  // session; kFailedPrecondition: it is no longer live, or it is not that node's at that epoch,
  // or that node no longer holds that epoch (design note 7). The node is part of the fence:
  // every node's epochs start at 1, and a session that moved (MoveSession) must not take a write
  // from its old node at an equal epoch.
  Status SetSessionState(int64_t id, SessionState state, int64_t at_us,
                         const std::string& reason = "", const SessionFence& fence = {});
  // A live session ends (`state` not live) with its trial metrics, in one transaction, under the
  // same fence as SetSessionState: a trial is recorded once, by the process that ran it.
  // `trace_json` (server/session/trace_recorder.h; "" for none) is kept as the session's record.
  Status EndSession(int64_t id, SessionState state, int64_t at_us, const std::string& reason,
                    const scoring::TrialMetrics& m, const SessionFence& fence = {},
                    const std::string& trace_json = "");
  // Live migration: a live session of `from` (at `from_epoch`, its row's) becomes `to`'s (at
  // `to.epoch`), in one transaction fenced by both leases: refused (kFailedPrecondition) unless
  // the session is live, belongs to `from` at that epoch, and both nodes are up at theirs. So a
  // session moves once, and never from a node the site has given up on (whose sessions it has
  // aborted) nor to one.
  // The reservation `placement` (ReservePlacement) is replaced by the moved session.
  Status MoveSession(int64_t id, const SessionFence& from, const SessionFence& to,
                     const std::string& placement = "");
  // At start-up: sessions a previous process of `node` left live (it was killed, or the machine
  // failed) cannot go on; they become aborted with `reason`. Returns how many.
  Expected<int> AbortOrphanedSessions(int64_t at_us, const std::string& reason,
                                      const std::string& node = "");

  // The node registry and its leases (design note 7). A row's heartbeat_us is when its lease was
  // last written (server/cluster: the replica a node beats to rewrites it every few seconds).
  // AcquireNode: `n.instance` takes the name `n.name` at `n.heartbeat_us` unless another
  // instance holds it (up, and its lease written within `lease_us`: kAlreadyExists, saying who
  // holds it); the epoch goes up by one, and the live sessions earlier holders left are aborted
  // with `reason`, in the same transaction.
  Expected<NodeLease> AcquireNode(const NodeRecord& n, int64_t lease_us, const std::string& reason);
  // The lease of the holder at `n.epoch` renewed at `n.heartbeat_us`, with its load.
  // kFailedPrecondition when that lease is lost (the node was marked down, or the name was taken
  // by a newer instance): the node must stop serving and acquire the name again.
  Status BeatNode(const NodeRecord& n);
  Expected<std::vector<NodeRecord>> ListNodes();
  // The node stopped answering: marked down unless a heartbeat came after `silent_since_us`,
  // and its live sessions aborted with `reason` (once, whichever control replica sees it first).
  // Returns how many sessions were aborted, or nullopt when the node was already down or alive.
  Expected<std::optional<int>> MarkNodeDown(const std::string& name, int64_t silent_since_us,
                                            int64_t at_us, const std::string& reason);
  // Live sessions per node, from the sessions' own rows (what placement balances).
  Expected<std::vector<std::pair<std::string, int>>> LiveSessionsByNode();
  // Every live session as (node, id), in one statement: placement counts from it and tells
  // which of its own just-answered placements the read already shows. Live sessions are bounded
  // by the nodes' capacities.
  Expected<std::vector<std::pair<std::string, int64_t>>> LiveSessionNodes();
  // Placement across control replicas (design note 8). One reservation at a time, site-wide,
  // reads every node's load (its live sessions and the placements reserved on it and not yet
  // answered) and `choose` picks a node from it, or none; a reservation on that node is written
  // in the same transaction, lasting until `expires_us` (a replica that died mid-placement holds
  // nothing past it). `choose` runs on the writer thread and may run again after a failure.
  struct Placement {
    std::string node, token;
  };
  using ChooseNode =
      std::function<std::optional<std::string>(const std::map<std::string, int>& load)>;
  Expected<std::optional<Placement>> ReservePlacement(int64_t expires_us, const ChooseNode& choose);
  // The reservation ends without a session (the node refused or did not answer), or after one
  // (a no-op once the node's row replaced it).
  Status ReleasePlacement(const std::string& token);
  Status RecordTrainingMoment(const std::string& trainee, double moment_min,
                              std::optional<int64_t> session_id);

  // Validates (scores 0–10 and finite, group, subject exists, a session subject was started (live
  // or ended), a moment within 0..kMaxMomentMin, evaluator's group) and stores one
  // row per index. The same idempotency key again → the first result with duplicate = true; the
  // same evaluator on the same subject and moment with another key → kAlreadyExists.
  Expected<SubmitResult> SubmitEvaluation(const Submission& s);
  void SubmitEvaluationAsync(Submission s, std::function<void(Expected<SubmitResult>)> done);

  // --- The training programme (design: server/domain/training.h) ---
  // A course with its exercises (positions 1…n in the order given); kAlreadyExists for a taken
  // name; `owner` must be a user.
  Expected<CourseRecord> CreateCourse(const CourseRecord& course);
  Status SetExerciseSpec(int64_t exercise_id, const std::string& spec_json);
  // A cohort of trainees (names; a trainee row is made for a name not seen before).
  Expected<CohortRecord> CreateCohort(const std::string& name, const std::string& instructor,
                                      const std::vector<std::string>& members);
  Status AddCohortMembers(int64_t cohort_id, const std::vector<std::string>& members);
  // A course for a cohort (cohort_id) or for one trainee (trainee); exactly one of the two.
  Expected<EnrolmentRecord> Enrol(const EnrolmentRecord& e);
  // A trainee whose trials set the benchmarks (or no longer); kNotFound for an unknown name.
  Status SetExpert(const std::string& trainee, bool expert);
  // Marks a live session, just created for `trainee`, as an attempt at `exercise_id` (once:
  // kFailedPrecondition when it already is one, or has ended).
  Status SetSessionExercise(int64_t session_id, int64_t exercise_id);

  Status PutWeightSet(const std::string& name, const std::string& json);
  Status RecordReport(const std::string& subject_kind, const std::string& subject,
                      const std::string& weights_json, const std::string& report_json);

  // --- Reads (pooled read-only connections) ---
  Expected<Principal> Authenticate(std::string_view token);
  Expected<std::vector<UserRecord>> ListUsers();
  Expected<SessionRecord> GetSession(int64_t id);
  Expected<std::vector<SessionRecord>> ListSessions(const std::optional<std::string>& trainee);
  Expected<std::optional<scoring::TrialMetrics>> GetTrialMetrics(int64_t session_id);
  // An ended session's record (JSON text); kNotFound when it has none (never driven, or ended
  // before records were kept).
  Expected<std::string> GetSessionTrace(int64_t session_id);
  Expected<SessionPage> FindSessions(const SessionQuery& q);
  // Every submission on one subject (a session's ratings, for its page and its trainee), oldest
  // first, with the evaluator's name and group.
  Expected<std::vector<SubmittedRow>> ListSubmissionsOn(SubjectKind kind,
                                                        const std::string& subject);
  Expected<std::string> GetWeightSet(const std::string& name);  // JSON; kNotFound
  Expected<std::vector<std::string>> ListWeightSets();
  Expected<std::vector<RatingRow>> LoadRatings(SubjectKind kind, const std::string& subject);
  Expected<std::vector<TrainingRow>> LoadTrainingRows();  // trainee subjects with a moment
  // An evaluator's own submissions, newest first (at most `limit`).
  Expected<std::vector<SubmittedRow>> ListSubmissionsBy(const std::string& evaluator, int limit);
  // The distinct subjects of a kind anyone has rated, by name.
  Expected<std::vector<std::string>> ListRatedSubjects(SubjectKind kind);
  Expected<int64_t> CountEvaluationRows();
  // The training programme's reads.
  Expected<std::vector<CourseRecord>> ListCourses();  // by name, with their exercises
  Expected<CourseRecord> GetCourse(int64_t id);       // kNotFound
  Expected<ExerciseRecord> GetExercise(int64_t id);   // kNotFound
  Expected<std::vector<CohortRecord>> ListCohorts();  // by name, with their members
  Expected<CohortRecord> GetCohort(int64_t id);       // kNotFound
  // Enrolments: all (trainee empty), or those that reach `trainee` (their own and their
  // cohorts'), oldest first.
  Expected<std::vector<EnrolmentRecord>> ListEnrolments(const std::string& trainee);
  Expected<std::vector<std::string>> ListExperts();  // by name
  // The recorded trials at the exercises of `course_id`, exercise by exercise (in the course's
  // order), each trainee's in the order they were made (their sessions' order); only `trainee`'s
  // when not empty, only the members' of `cohort_id` when not 0, only at `exercise_id` when
  // not 0, only the trainees named within `names` when given (a page of a cohort's grid).
  Expected<std::vector<AttemptRow>> LoadAttempts(int64_t course_id, const std::string& trainee,
                                                 int64_t cohort_id, int64_t exercise_id = 0,
                                                 const std::optional<NameRange>& names = {});
  // The experts' recorded trials on `scene` (any session, an exercise's or not), in no order;
  // only those at `exercise_id` when not 0.
  Expected<std::vector<AttemptRow>> LoadExpertAttempts(const std::string& scene,
                                                       int64_t exercise_id = 0);
  // The exercise a session was an attempt at (0: none).
  Expected<int64_t> SessionExercise(int64_t session_id);

  // Streams one line per stored score (CSV with a header, JSON lines) or one xAPI statement
  // per submission (JSON lines) to `sink` in chunks; `sink` returning false stops the export.
  Status Export(const ExportFilter& filter, ExportFormat format,
                const std::function<bool(std::string_view)>& sink);
  // Online backup to a new file (the store stays usable meanwhile). SQLite only: a PostgreSQL
  // store is backed up by pg_dump or pg_basebackup (kFailedPrecondition here).
  Status Backup(const std::string& destination);
  Expected<std::string> IntegrityCheck();  // "ok" when sound
  Backend backend() const;

  StoreStats stats() const;

 private:
  struct Impl;
  explicit Store(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The store's clock and time format (common/core/time.h), under the names its callers use.
using vsurg::IsoTimeUtc;
using vsurg::NowUs;

}  // namespace vsurg::db
