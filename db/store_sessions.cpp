#include <cmath>

#include "db/store_impl.h"

// Sessions (their state and times), a session's trial metrics, and training moments.
namespace vsurg::db {

namespace {

Expected<int64_t> EnsureTrainee(Connection& c, const std::string& trainee) {
  if (trainee.empty() || trainee.size() > 128)
    return InvalidArgument("trainee", "a trainee name of 1 to 128 characters is required");
  Status s = RunSql(c, "INSERT INTO trainees(name) VALUES (?1) ON CONFLICT(name) DO NOTHING",
                    [&](Statement& st) { st.Bind(1, trainee); });
  if (!s.ok()) return s.error();
  auto id = LookupId(c, "SELECT id FROM trainees WHERE name = ?1", trainee);
  if (!id.ok()) return id.error();
  return **id;
}

void ReadSession(Statement& st, SessionRecord& s) {
  s.id = st.Int(0);
  s.trainee = st.String(1);
  s.scene = st.String(2);
  // A name this binary does not know cannot be written by it; read as aborted, never live.
  s.state = ParseSessionState(st.Text(3)).value_or(SessionState::kAborted);
  s.created_us = st.Int(4);
  s.started_us = st.IsNull(5) ? 0 : st.Int(5);
  s.ended_us = st.IsNull(6) ? 0 : st.Int(6);
  s.end_reason = st.String(7);
}

constexpr const char* kSessionColumns =
    "SELECT s.id, t.name, s.scene, s.state, s.created_us, s.started_us, s.ended_us, "
    "s.end_reason FROM sessions s JOIN trainees t ON t.id = s.trainee_id ";

}  // namespace

Expected<SessionRecord> Store::CreateSession(const std::string& trainee, const std::string& scene) {
  SessionRecord rec;
  rec.trainee = trainee;
  rec.scene = scene;
  rec.state = SessionState::kCreated;
  rec.created_us = NowUs();
  Status s = Write([&](Connection& c) -> Status {
    auto tid = EnsureTrainee(c, trainee);
    if (!tid.ok()) return tid.error();
    if (scene.empty()) return InvalidArgument("scene", "a scene name is required");
    Status st = RunSql(c,
                       "INSERT INTO scenes(name, first_used_us) VALUES (?1, ?2) "
                       "ON CONFLICT(name) DO NOTHING",
                       [&](Statement& q) { q.Bind(1, scene).Bind(2, rec.created_us); });
    if (!st.ok()) return st;
    st = RunSql(c,
                "INSERT INTO sessions(trainee_id, scene, state, created_us) "
                "VALUES (?1, ?2, ?3, ?4)",
                [&](Statement& q) {
                  q.Bind(1, *tid).Bind(2, scene).Bind(3, SessionStateName(rec.state));
                  q.Bind(4, rec.created_us);
                });
    if (!st.ok()) return st;
    auto id = c.LastInsertId();
    if (!id.ok()) return id.error();
    rec.id = *id;
    return st;
  });
  if (!s.ok()) return s.error();
  return rec;
}

Status Store::SetSessionState(int64_t id, SessionState state, int64_t at_us,
                              const std::string& reason) {
  return Write([=](Connection& c) -> Status {
    Status s = RunSql(
        c,
        "UPDATE sessions SET state = ?2, "
        "started_us = CASE WHEN ?5 AND started_us IS NULL THEN ?3 ELSE started_us END, "
        "ended_us = CASE WHEN ?6 THEN ?3 ELSE ended_us END, "
        "end_reason = CASE WHEN ?4 <> '' THEN ?4 ELSE end_reason END "
        "WHERE id = ?1",
        [&](Statement& st) {
          st.Bind(1, id).Bind(2, SessionStateName(state)).Bind(3, at_us).Bind(4, reason);
          st.Bind(5, int64_t{state == SessionState::kRunning}).Bind(6, int64_t{!IsLive(state)});
        });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no session " + std::to_string(id), "session"};
    return s;
  });
}

Expected<int> Store::AbortOrphanedSessions(int64_t at_us, const std::string& reason) {
  int changed = 0;
  Status s = Write([=, &changed](Connection& c) -> Status {
    Status st = RunSql(c,
                       "UPDATE sessions SET state = ?3, ended_us = ?1, end_reason = ?2 "
                       "WHERE state IN (?4, ?5, ?6)",
                       [&](Statement& q) {
                         q.Bind(1, at_us).Bind(2, reason);
                         q.Bind(3, SessionStateName(SessionState::kAborted));
                         q.Bind(4, SessionStateName(SessionState::kCreated));
                         q.Bind(5, SessionStateName(SessionState::kRunning));
                         q.Bind(6, SessionStateName(SessionState::kStalled));
                       });
    if (st.ok()) changed = c.Changes();
    return st;
  });
  if (!s.ok()) return s.error();
  return changed;
}

Status Store::RecordTrialMetrics(int64_t session_id, const scoring::TrialMetrics& m) {
  return Write([=](Connection& c) {
    return RunSql(
        c,
        "INSERT INTO trial_metrics(session_id, completed, completion_time_s, task_error, "
        "peak_force_n, time_over_force_limit_s, path_length_m, rms_jerk, overload_events, "
        "duration_s, score, raw_score, caps, recorded_us) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14) "
        "ON CONFLICT(session_id) DO UPDATE SET completed = excluded.completed, "
        "completion_time_s = excluded.completion_time_s, task_error = excluded.task_error, "
        "peak_force_n = excluded.peak_force_n, "
        "time_over_force_limit_s = excluded.time_over_force_limit_s, "
        "path_length_m = excluded.path_length_m, rms_jerk = excluded.rms_jerk, "
        "overload_events = excluded.overload_events, duration_s = excluded.duration_s, "
        "score = excluded.score, raw_score = excluded.raw_score, caps = excluded.caps, "
        "recorded_us = excluded.recorded_us",
        [&](Statement& st) {
          st.Bind(1, session_id).Bind(2, int64_t{m.completed ? 1 : 0});
          st.Bind(3, m.completion_time).Bind(4, m.task_error).Bind(5, m.peak_force);
          st.Bind(6, m.time_over_force_limit).Bind(7, m.path_length).Bind(8, m.rms_jerk);
          st.Bind(9, int64_t{m.overload_events}).Bind(10, m.duration).Bind(11, m.score);
          st.Bind(12, m.raw_score).Bind(13, int64_t{m.caps}).Bind(14, NowUs());
        });
  });
}

Status Store::RecordTrainingMoment(const std::string& trainee, double moment_min,
                                   std::optional<int64_t> session_id) {
  if (!std::isfinite(moment_min) || moment_min < 0)
    return InvalidArgument("moment_min", "must be finite and >= 0 minutes");
  return Write([=](Connection& c) -> Status {
    auto tid = EnsureTrainee(c, trainee);
    if (!tid.ok()) return tid.error();
    return RunSql(c,
                  "INSERT INTO training_moments(trainee_id, moment_min, session_id, recorded_us) "
                  "VALUES (?1, ?2, ?3, ?4)",
                  [&](Statement& st) {
                    st.Bind(1, *tid).Bind(2, moment_min);
                    if (session_id) {
                      st.Bind(3, *session_id);
                    } else {
                      st.BindNull(3);
                    }
                    st.Bind(4, NowUs());
                  });
  });
}

Expected<SessionRecord> Store::GetSession(int64_t id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(std::string(kSessionColumns) + "WHERE s.id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kNotFound, "no session " + std::to_string(id), "session"};
  }
  SessionRecord s;
  ReadSession(**st, s);
  (*st)->Reset();
  return s;
}

Expected<std::vector<SessionRecord>> Store::ListSessions(
    const std::optional<std::string>& trainee) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(std::string(kSessionColumns) +
                          "WHERE (CAST(?1 AS TEXT) IS NULL OR t.name = ?1) ORDER BY s.id");
  if (!st.ok()) return st.error();
  if (trainee) {
    (*st)->Bind(1, *trainee);
  } else {
    (*st)->BindNull(1);
  }
  std::vector<SessionRecord> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    ReadSession(**st, out.emplace_back());
  }
  (*st)->Reset();
  return out;
}

Expected<std::optional<scoring::TrialMetrics>> Store::GetTrialMetrics(int64_t session_id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT completed, completion_time_s, task_error, peak_force_n, time_over_force_limit_s, "
      "path_length_m, rms_jerk, overload_events, duration_s, score, raw_score, caps "
      "FROM trial_metrics WHERE session_id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, session_id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  std::optional<scoring::TrialMetrics> out;
  if (*row) {
    Statement& q = **st;
    scoring::TrialMetrics m;
    m.completed = q.Int(0) != 0;
    m.completion_time = q.Double(1);
    m.task_error = q.Double(2);
    m.peak_force = q.Double(3);
    m.time_over_force_limit = q.Double(4);
    m.path_length = q.Double(5);
    m.rms_jerk = q.Double(6);
    m.overload_events = static_cast<int>(q.Int(7));
    m.duration = q.Double(8);
    m.score = q.Double(9);
    m.raw_score = q.Double(10);
    m.caps = static_cast<uint32_t>(q.Int(11));
    out = m;
  }
  (*st)->Reset();
  return out;
}

}  // namespace vsurg::db
