#include <cmath>
#include <map>

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
  s.node = st.String(8);
}

constexpr const char* kSessionColumns =
    "SELECT s.id, t.name, s.scene, s.state, s.created_us, s.started_us, s.ended_us, "
    "s.end_reason, s.node FROM sessions s JOIN trainees t ON t.id = s.trainee_id ";

// Binds the three live states' names at ?first, ?first+1, ?first+2.
void BindLiveStates(Statement& q, int first) {
  q.Bind(first, SessionStateName(SessionState::kCreated));
  q.Bind(first + 1, SessionStateName(SessionState::kRunning));
  q.Bind(first + 2, SessionStateName(SessionState::kStalled));
}

}  // namespace

Expected<SessionRecord> Store::CreateSession(const std::string& trainee, const std::string& scene,
                                             const std::string& node) {
  SessionRecord rec;
  rec.node = node;
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
                "INSERT INTO sessions(trainee_id, scene, state, created_us, node) "
                "VALUES (?1, ?2, ?3, ?4, ?5)",
                [&](Statement& q) {
                  q.Bind(1, *tid).Bind(2, scene).Bind(3, SessionStateName(rec.state));
                  q.Bind(4, rec.created_us).Bind(5, node);
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

namespace {

// Aborts the live sessions of `node` inside a write job; their count.
Expected<int> AbortLiveSessionsOf(Connection& c, const std::string& node, int64_t at_us,
                                  const std::string& reason) {
  Status st = RunSql(c,
                     "UPDATE sessions SET state = ?3, ended_us = ?1, end_reason = ?2 "
                     "WHERE node = ?4 AND state IN (?5, ?6, ?7)",
                     [&](Statement& q) {
                       q.Bind(1, at_us).Bind(2, reason);
                       q.Bind(3, SessionStateName(SessionState::kAborted)).Bind(4, node);
                       BindLiveStates(q, 5);
                     });
  if (!st.ok()) return st.error();
  return c.Changes();
}

}  // namespace

Expected<int> Store::AbortOrphanedSessions(int64_t at_us, const std::string& reason,
                                           const std::string& node) {
  int changed = 0;
  Status s = Write([=, &changed](Connection& c) -> Status {
    auto n = AbortLiveSessionsOf(c, node, at_us, reason);
    if (!n.ok()) return n.error();
    changed = *n;
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return changed;
}

Status Store::PutNode(const NodeRecord& n) {
  if (n.name.empty() || n.name.size() > 64)
    return InvalidArgument("name", "a node name of 1 to 64 characters is required");
  return Write([n](Connection& c) {
    return RunSql(c,
                  "INSERT INTO nodes(name, grpc_address, udp_host, udp_port, capacity, sessions, "
                  "cpu, draining, down, started_us, heartbeat_us) "
                  "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, 0, ?9, ?10) "
                  "ON CONFLICT(name) DO UPDATE SET grpc_address = excluded.grpc_address, "
                  "udp_host = excluded.udp_host, udp_port = excluded.udp_port, "
                  "capacity = excluded.capacity, sessions = excluded.sessions, "
                  "cpu = excluded.cpu, draining = excluded.draining, down = 0, "
                  "started_us = excluded.started_us, heartbeat_us = excluded.heartbeat_us",
                  [&](Statement& q) {
                    q.Bind(1, n.name).Bind(2, n.grpc_address).Bind(3, n.udp_host);
                    q.Bind(4, int64_t{n.udp_port}).Bind(5, int64_t{n.capacity});
                    q.Bind(6, int64_t{n.sessions}).Bind(7, n.cpu);
                    q.Bind(8, int64_t{n.draining ? 1 : 0}).Bind(9, n.started_us);
                    q.Bind(10, n.heartbeat_us);
                  });
  });
}

Expected<std::vector<NodeRecord>> Store::ListNodes() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT name, grpc_address, udp_host, udp_port, capacity, sessions, cpu, draining, down, "
      "started_us, heartbeat_us FROM nodes ORDER BY name");
  if (!st.ok()) return st.error();
  std::vector<NodeRecord> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    Statement& q = **st;
    NodeRecord& n = out.emplace_back();
    n.name = q.String(0);
    n.grpc_address = q.String(1);
    n.udp_host = q.String(2);
    n.udp_port = static_cast<int>(q.Int(3));
    n.capacity = static_cast<int>(q.Int(4));
    n.sessions = static_cast<int>(q.Int(5));
    n.cpu = q.Double(6);
    n.draining = q.Int(7) != 0;
    n.down = q.Int(8) != 0;
    n.started_us = q.Int(9);
    n.heartbeat_us = q.Int(10);
  }
  (*st)->Reset();
  return out;
}

Expected<std::optional<int>> Store::MarkNodeDown(const std::string& name, int64_t silent_since_us,
                                                 int64_t at_us, const std::string& reason) {
  std::optional<int> aborted;
  Status s = Write([&](Connection& c) -> Status {
    // Only the first to see the silence marks it, and only if no heartbeat came meanwhile.
    Status st = RunSql(c,
                       "UPDATE nodes SET down = 1 WHERE name = ?1 AND down = 0 AND "
                       "heartbeat_us < ?2",
                       [&](Statement& q) { q.Bind(1, name).Bind(2, silent_since_us); });
    if (!st.ok() || c.Changes() == 0) return st;
    auto n = AbortLiveSessionsOf(c, name, at_us, reason);
    if (!n.ok()) return n.error();
    aborted = *n;
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return aborted;
}

Expected<std::vector<std::pair<std::string, int64_t>>> Store::LiveSessionNodes() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT node, id FROM sessions WHERE state IN (?1, ?2, ?3)");
  if (!st.ok()) return st.error();
  BindLiveStates(**st, 1);
  std::vector<std::pair<std::string, int64_t>> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    out.emplace_back((*st)->String(0), (*st)->Int(1));
  }
  (*st)->Reset();
  return out;
}

Expected<std::vector<std::pair<std::string, int>>> Store::LiveSessionsByNode() {
  auto rows = LiveSessionNodes();
  if (!rows.ok()) return rows.error();
  std::map<std::string, int> by_node;  // ordered by node
  for (const auto& [node, id] : *rows) ++by_node[node];
  return std::vector<std::pair<std::string, int>>(by_node.begin(), by_node.end());
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
