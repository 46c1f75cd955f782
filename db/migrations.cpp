#include "db/migrations.h"

#include <string>

#include "db/connection.h"

namespace vsurg::db {

const std::vector<const char*>& Migrations() {
  static const std::vector<const char*> kMigrations = {
      // 1: the initial schema.
      R"sql(
CREATE TABLE users (
  id          INTEGER PRIMARY KEY,
  name        TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 128),
  role        TEXT NOT NULL CHECK (role IN ('trainee', 'instructor', 'evaluator', 'admin')),
  created_us  INTEGER NOT NULL,
  disabled    INTEGER NOT NULL DEFAULT 0 CHECK (disabled IN (0, 1))
);
CREATE TABLE tokens (
  id          INTEGER PRIMARY KEY,
  user_id     INTEGER NOT NULL REFERENCES users(id) ON DELETE CASCADE,
  hash        BLOB NOT NULL UNIQUE CHECK (length(hash) = 32),
  label       TEXT NOT NULL DEFAULT '',
  created_us  INTEGER NOT NULL,
  revoked     INTEGER NOT NULL DEFAULT 0 CHECK (revoked IN (0, 1))
);
CREATE TABLE trainees (
  id            INTEGER PRIMARY KEY,
  name          TEXT NOT NULL UNIQUE,
  trainee_group TEXT NOT NULL DEFAULT '',
  user_id       INTEGER UNIQUE REFERENCES users(id)
);
CREATE TABLE evaluators (
  id              INTEGER PRIMARY KEY,
  name            TEXT NOT NULL UNIQUE,
  evaluator_group TEXT NOT NULL CHECK (evaluator_group IN ('intern', 'associate_chief', 'chief')),
  user_id         INTEGER UNIQUE REFERENCES users(id)
);
CREATE TABLE scenes (
  name        TEXT PRIMARY KEY,
  first_used_us INTEGER NOT NULL
);
CREATE TABLE sessions (
  id          INTEGER PRIMARY KEY,
  trainee_id  INTEGER NOT NULL REFERENCES trainees(id),
  scene       TEXT NOT NULL REFERENCES scenes(name),
  state       TEXT NOT NULL CHECK (state IN ('created', 'running', 'stalled', 'ended',
                                             'disconnected', 'aborted')),
  created_us  INTEGER NOT NULL,
  started_us  INTEGER,
  ended_us    INTEGER,
  end_reason  TEXT NOT NULL DEFAULT ''
);
CREATE INDEX sessions_by_trainee ON sessions(trainee_id);
CREATE TABLE trial_metrics (
  session_id              INTEGER PRIMARY KEY REFERENCES sessions(id),
  completed               INTEGER NOT NULL,
  completion_time_s       REAL NOT NULL,
  task_error              REAL NOT NULL,
  peak_force_n            REAL NOT NULL,
  time_over_force_limit_s REAL NOT NULL,
  path_length_m           REAL NOT NULL,
  rms_jerk                REAL NOT NULL,
  overload_events         INTEGER NOT NULL,
  duration_s              REAL NOT NULL,
  score                   REAL NOT NULL CHECK (score BETWEEN 0 AND 10),
  raw_score               REAL NOT NULL,
  caps                    INTEGER NOT NULL,
  recorded_us             INTEGER NOT NULL
);
CREATE TABLE training_moments (
  id          INTEGER PRIMARY KEY,
  trainee_id  INTEGER NOT NULL REFERENCES trainees(id),
  moment_min  REAL NOT NULL CHECK (moment_min >= 0),
  session_id  INTEGER REFERENCES sessions(id),
  recorded_us INTEGER NOT NULL,
  UNIQUE (trainee_id, moment_min)
);
CREATE TABLE submissions (
  id              INTEGER PRIMARY KEY,
  idempotency_key TEXT NOT NULL UNIQUE CHECK (length(idempotency_key) BETWEEN 1 AND 128),
  evaluator_id    INTEGER NOT NULL REFERENCES evaluators(id),
  evaluator_group TEXT NOT NULL CHECK (evaluator_group IN ('intern', 'associate_chief', 'chief')),
  subject_kind    TEXT NOT NULL CHECK (subject_kind IN ('session', 'trainee', 'model')),
  subject         TEXT NOT NULL CHECK (length(subject) BETWEEN 1 AND 256),
  moment_min      REAL CHECK (moment_min IS NULL OR moment_min >= 0),
  submitted_us    INTEGER NOT NULL,
  submitted_by    INTEGER NOT NULL REFERENCES users(id)
);
CREATE UNIQUE INDEX one_submission_per_rater
  ON submissions(evaluator_id, subject_kind, subject, ifnull(moment_min, -1));
CREATE INDEX submissions_by_time ON submissions(submitted_us);
CREATE INDEX submissions_by_subject ON submissions(subject_kind, subject);
-- One row per evaluator per subject per index: the raw scores.
CREATE TABLE evaluations (
  submission_id INTEGER NOT NULL REFERENCES submissions(id) ON DELETE CASCADE,
  index_no      INTEGER NOT NULL CHECK (index_no BETWEEN 1 AND 9),
  score         REAL NOT NULL CHECK (score BETWEEN 0 AND 10),
  PRIMARY KEY (submission_id, index_no)
) WITHOUT ROWID;
CREATE TABLE weight_sets (
  name        TEXT PRIMARY KEY,
  json        TEXT NOT NULL CHECK (json_valid(json)),
  created_us  INTEGER NOT NULL
);
CREATE TABLE reports (
  id           INTEGER PRIMARY KEY,
  subject_kind TEXT NOT NULL,
  subject      TEXT NOT NULL,
  weights_json TEXT NOT NULL CHECK (json_valid(weights_json)),
  report_json  TEXT NOT NULL CHECK (json_valid(report_json)),
  created_us   INTEGER NOT NULL
);
)sql",
      // 2: several simulation nodes on one store (DESIGN.md "Beyond one machine"): the node a
      // session runs on ('' in the all-in-one server), and the nodes' registry with their last
      // heartbeat and load.
      R"sql(
ALTER TABLE sessions ADD COLUMN node TEXT NOT NULL DEFAULT '';
CREATE INDEX sessions_by_node_state ON sessions(node, state);
CREATE TABLE nodes (
  name          TEXT PRIMARY KEY CHECK (length(name) BETWEEN 1 AND 64),
  grpc_address  TEXT NOT NULL,
  udp_host      TEXT NOT NULL,
  udp_port      INTEGER NOT NULL CHECK (udp_port BETWEEN 1 AND 65535),
  capacity      INTEGER NOT NULL CHECK (capacity >= 0),
  sessions      INTEGER NOT NULL CHECK (sessions >= 0),
  cpu           REAL NOT NULL,
  draining      INTEGER NOT NULL DEFAULT 0 CHECK (draining IN (0, 1)),
  down          INTEGER NOT NULL DEFAULT 0 CHECK (down IN (0, 1)),
  started_us    INTEGER NOT NULL,
  heartbeat_us  INTEGER NOT NULL
);
)sql",
      // 3: leases and fencing (DESIGN.md "Leases and fencing"). A node name is held by
      // one process at a time (`instance`); each acquisition of the name is a new `epoch`, and a
      // session carries the epoch of the node process that created it. The store refuses a
      // session write whose epoch is not its node's current one, or whose node is down.
      R"sql(
ALTER TABLE nodes ADD COLUMN epoch INTEGER NOT NULL DEFAULT 0;
ALTER TABLE nodes ADD COLUMN instance TEXT NOT NULL DEFAULT '';
ALTER TABLE sessions ADD COLUMN epoch INTEGER NOT NULL DEFAULT 0;
)sql",
      // 4: what the station rendered and how the link held, beside the server's figures
      // (scoring::LinkFigures; 0 for trials recorded before, and for stations that do not say).
      R"sql(
ALTER TABLE trial_metrics ADD COLUMN station_peak_force_n REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN station_time_over_limit_s REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN link_rtt_ms REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN link_jitter_ms REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN link_loss_ratio REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN link_rate_hz REAL NOT NULL DEFAULT 0;
)sql",
      // 5: sessions as records (the dashboard's session page and replay): each ended session's
      // traces and surface frames (server/session/trace_recorder.h), and an evaluator's comment.
      R"sql(
CREATE TABLE session_traces (
  session_id  INTEGER PRIMARY KEY REFERENCES sessions(id),
  trace_json  TEXT NOT NULL CHECK (json_valid(trace_json))
);
ALTER TABLE submissions ADD COLUMN comment TEXT NOT NULL DEFAULT '';
CREATE INDEX sessions_by_scene_time ON sessions(scene, created_us);
)sql",
      // 6: the training programme (server/domain/training.h): courses of exercises with their
      // proficiency targets and rules (spec_json), cohorts of trainees with an instructor,
      // enrolments of a cohort or of one trainee in a course, the experts whose trials set
      // benchmarks, and the exercise a session was an attempt at.
      R"sql(
ALTER TABLE trainees ADD COLUMN expert INTEGER NOT NULL DEFAULT 0 CHECK (expert IN (0, 1));
CREATE TABLE courses (
  id           INTEGER PRIMARY KEY,
  name         TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 128),
  description  TEXT NOT NULL DEFAULT '',
  owner_id     INTEGER NOT NULL REFERENCES users(id),
  created_us   INTEGER NOT NULL
);
CREATE TABLE exercises (
  id         INTEGER PRIMARY KEY,
  course_id  INTEGER NOT NULL REFERENCES courses(id),
  position   INTEGER NOT NULL CHECK (position >= 1),
  title      TEXT NOT NULL CHECK (length(title) BETWEEN 1 AND 128),
  scene      TEXT NOT NULL CHECK (length(scene) BETWEEN 1 AND 128),
  spec_json  TEXT NOT NULL CHECK (json_valid(spec_json)),
  UNIQUE (course_id, position)
);
CREATE TABLE cohorts (
  id             INTEGER PRIMARY KEY,
  name           TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 128),
  instructor_id  INTEGER NOT NULL REFERENCES users(id),
  created_us     INTEGER NOT NULL
);
CREATE TABLE cohort_members (
  cohort_id   INTEGER NOT NULL REFERENCES cohorts(id),
  trainee_id  INTEGER NOT NULL REFERENCES trainees(id),
  PRIMARY KEY (cohort_id, trainee_id)
);
CREATE TABLE enrolments (
  id          INTEGER PRIMARY KEY,
  course_id   INTEGER NOT NULL REFERENCES courses(id),
  cohort_id   INTEGER REFERENCES cohorts(id),
  trainee_id  INTEGER REFERENCES trainees(id),
  starts_us   INTEGER NOT NULL,
  ends_us     INTEGER,
  created_us  INTEGER NOT NULL,
  CHECK ((cohort_id IS NULL) <> (trainee_id IS NULL))
);
ALTER TABLE sessions ADD COLUMN exercise_id INTEGER REFERENCES exercises(id);
CREATE INDEX sessions_by_exercise ON sessions(exercise_id, trainee_id);
CREATE INDEX sessions_by_scene_trainee ON sessions(scene, trainee_id);
)sql",
      // 7: placements in flight across control replicas (Store::ReservePlacement): each Create
      // a replica sent to a node and the node has not yet answered with its session's row.
      R"sql(
CREATE TABLE placements (
  token       TEXT PRIMARY KEY,
  node        TEXT NOT NULL,
  expires_us  INTEGER NOT NULL
);
)sql",
      // 8: four-handed training: how much of a trial an instructor's hand was on the tool
      // (scoring::TrialMetrics::guided_share, guided_alpha; 0 for trials alone).
      R"sql(
ALTER TABLE trial_metrics ADD COLUMN guided_share REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN guided_alpha REAL NOT NULL DEFAULT 0;
)sql",
      // 9: palpation (scoring::TrialMetrics::lumps … mean_force; 0 for the other tasks).
      R"sql(
ALTER TABLE trial_metrics ADD COLUMN lumps INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN lumps_found INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN false_marks INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN localisation_error_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN coverage REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN mean_force_n REAL NOT NULL DEFAULT 0;
)sql",
      // 10: needle insertion (scoring::TrialMetrics::depth_error … lateral_strain; 0 for the
      // other tasks).
      R"sql(
ALTER TABLE trial_metrics ADD COLUMN depth_error_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN path_deviation_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN punctures INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN extra_punctures INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN back_wall_breaches INTEGER NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN lateral_strain REAL NOT NULL DEFAULT 0;
)sql",
      // 11: pattern cutting (scoring::TrialMetrics::cut_deviation_max … cut_lifts; 0 for the
      // other tasks).
      R"sql(
ALTER TABLE trial_metrics ADD COLUMN cut_deviation_max_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN cut_outside_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN torn_length_m REAL NOT NULL DEFAULT 0;
ALTER TABLE trial_metrics ADD COLUMN cut_lifts INTEGER NOT NULL DEFAULT 0;
)sql",
  };
  return kMigrations;
}

Status Migrate(Connection& c) {
  const auto& migrations = Migrations();
  const int latest = static_cast<int>(migrations.size());
  // One transaction per migration, under the schema lock: control replicas that start together
  // on one PostgreSQL apply each migration once, the others find it done.
  for (;;) {
    if (Status s = c.BeginWrite(); !s.ok()) return s;
    Status s = c.LockSchema();
    auto version = s.ok() ? c.SchemaVersion() : Expected<int>(s.error());
    if (!version.ok()) {
      (void)c.Exec("ROLLBACK");
      return version.error();
    }
    if (*version > latest) {
      (void)c.Exec("ROLLBACK");
      return Error{ErrorCode::kFailedPrecondition,
                   "the database is at schema version " + std::to_string(*version) +
                       ", newer than this binary's " + std::to_string(latest) +
                       "; use a newer vsurg",
                   "user_version"};
    }
    if (*version == latest) return c.Exec("COMMIT");
    const std::string ddl = c.Dialect(migrations[static_cast<size_t>(*version)]);
    s = c.Exec(ddl.c_str());
    if (s.ok()) s = c.SetSchemaVersion(*version + 1);
    if (s.ok()) s = c.Exec("COMMIT");
    if (!s.ok()) {
      (void)c.Exec("ROLLBACK");
      return Error{s.error().code,
                   "migration " + std::to_string(*version + 1) + ": " + s.error().message,
                   "user_version"};
    }
  }
}

}  // namespace vsurg::db
