#include <algorithm>
#include <cmath>
#include <future>
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

}  // namespace

void BindLiveStates(Statement& q, int first) {
  q.Bind(first, SessionStateName(SessionState::kCreated));
  q.Bind(first + 1, SessionStateName(SessionState::kRunning));
  q.Bind(first + 2, SessionStateName(SessionState::kStalled));
}

namespace {

// Design note 7's locks on a node's row. PostgreSQL: a session write holds it FOR KEY SHARE
// (any number at once, until COMMIT), and a heartbeat's UPDATE, which changes no key column,
// takes FOR NO KEY UPDATE, which does not wait for them: a node's long session transactions (a
// trial's record) never hold up the control plane's lease renewals. Declaring the node down and
// taking its name (NodeRowForUpdate) lock it FOR UPDATE, which waits for every session write in
// flight and makes each later one wait, and then re-check it: no session write of an epoch
// straddles either. SQLite has one writer at a time, which already orders them all.
Status NodeRowForUpdate(Connection& c, const std::string& node) {
  if (c.backend() != Backend::kPostgres) return Status::Ok();
  auto st = c.Prepare("SELECT 1 FROM nodes WHERE name = ?1 FOR UPDATE");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, node);
  auto row = (*st)->Step();
  (*st)->Reset();
  if (!row.ok()) return row.error();
  return Status::Ok();
}

// A session write's fence: the node's row held (above) when `node` is up at `epoch`; else a
// refusal. The all-in-one server's sessions (node "") have no lease.
Status HoldFence(Connection& c, const std::string& node, int64_t epoch) {
  if (node.empty()) {
    if (epoch == 0) return Status::Ok();
    return Error{ErrorCode::kFailedPrecondition, "an epoch without a node", "epoch"};
  }
  // PostgreSQL re-checks the condition on the row's newest version after waiting for a lock.
  auto st = c.Prepare(c.backend() == Backend::kPostgres
                          ? "SELECT 1 FROM nodes WHERE name = ?1 AND epoch = ?2 AND down = 0 "
                            "FOR KEY SHARE"
                          : "SELECT 1 FROM nodes WHERE name = ?1 AND epoch = ?2 AND down = 0");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, node).Bind(2, epoch);
  auto row = (*st)->Step();
  (*st)->Reset();
  if (!row.ok()) return row.error();
  if (!*row)
    return Error{ErrorCode::kFailedPrecondition,
                 "node " + node + " no longer holds the lease of epoch " + std::to_string(epoch) +
                     " (marked down, or its name taken by a newer process): write refused",
                 "epoch"};
  return Status::Ok();
}

// The session's node and epoch, for a write to it; kNotFound when there is no such session.
Expected<std::pair<std::string, int64_t>> SessionOwner(Connection& c, int64_t id) {
  auto st = c.Prepare("SELECT node, epoch FROM sessions WHERE id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kNotFound, "no session " + std::to_string(id), "session"};
  }
  std::pair<std::string, int64_t> out{(*st)->String(0), (*st)->Int(1)};
  (*st)->Reset();
  return out;
}

// Inside a write job: the fence of session `id` for a writer at `epoch`, then the state change,
// only from a live state. kFailedPrecondition when the session is no longer live.
Status ChangeLiveSession(Connection& c, int64_t id, SessionState state, int64_t at_us,
                         const std::string& reason, const SessionFence& fence) {
  auto owner = SessionOwner(c, id);
  if (!owner.ok()) return owner.error();
  const int64_t epoch = fence.epoch;
  if (owner->first != fence.node || owner->second != epoch)
    return Error{ErrorCode::kFailedPrecondition,
                 "session " + std::to_string(id) + " belongs to epoch " +
                     std::to_string(owner->second) + " of node '" + owner->first +
                     "', not to epoch " + std::to_string(epoch) + " of '" + fence.node +
                     "': write refused",
                 "epoch"};
  if (Status f = HoldFence(c, owner->first, epoch); !f.ok()) return f;
  Status s = RunSql(
      c,
      "UPDATE sessions SET state = ?2, "
      "started_us = CASE WHEN ?5 AND started_us IS NULL THEN ?3 ELSE started_us END, "
      "ended_us = CASE WHEN ?6 THEN ?3 ELSE ended_us END, "
      "end_reason = CASE WHEN ?4 <> '' THEN ?4 ELSE end_reason END "
      "WHERE id = ?1 AND state IN (?7, ?8, ?9)",
      [&](Statement& st) {
        st.Bind(1, id).Bind(2, SessionStateName(state)).Bind(3, at_us).Bind(4, reason);
        st.Bind(5, int64_t{state == SessionState::kRunning}).Bind(6, int64_t{!IsLive(state)});
        BindLiveStates(st, 7);
      });
  if (s.ok() && c.Changes() == 0)
    return Error{ErrorCode::kFailedPrecondition,
                 "session " + std::to_string(id) + " has ended: it never changes again", "session"};
  return s;
}

}  // namespace

Expected<SessionRecord> Store::CreateSession(const std::string& trainee, const std::string& scene,
                                             const SessionFence& fence,
                                             const std::string& placement) {
  SessionRecord rec;
  rec.node = fence.node;
  rec.trainee = trainee;
  rec.scene = scene;
  rec.state = SessionState::kCreated;
  rec.created_us = NowUs();
  Status s = Write([&](Connection& c) -> Status {
    if (Status f = HoldFence(c, fence.node, fence.epoch); !f.ok()) return f;
    if (Status p = EndPlacement(c, placement); !p.ok()) return p;
    auto tid = EnsureTrainee(c, trainee);
    if (!tid.ok()) return tid.error();
    if (scene.empty()) return InvalidArgument("scene", "a scene name is required");
    Status st = RunSql(c,
                       "INSERT INTO scenes(name, first_used_us) VALUES (?1, ?2) "
                       "ON CONFLICT(name) DO NOTHING",
                       [&](Statement& q) { q.Bind(1, scene).Bind(2, rec.created_us); });
    if (!st.ok()) return st;
    st = RunSql(c,
                "INSERT INTO sessions(trainee_id, scene, state, created_us, node, epoch) "
                "VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                [&](Statement& q) {
                  q.Bind(1, *tid).Bind(2, scene).Bind(3, SessionStateName(rec.state));
                  q.Bind(4, rec.created_us).Bind(5, fence.node).Bind(6, fence.epoch);
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
                              const std::string& reason, const SessionFence& fence) {
  return Write([=](Connection& c) -> Status {
    return ChangeLiveSession(c, id, state, at_us, reason, fence);
  });
}

Status Store::EndSession(int64_t id, SessionState state, int64_t at_us, const std::string& reason,
                         const scoring::TrialMetrics& m, const SessionFence& fence,
                         const std::string& trace_json) {
  if (IsLive(state))
    return InvalidArgument(
        "state", std::string("a session ends in a final state, not ") + SessionStateName(state));
  return Write([=](Connection& c) -> Status {
    if (Status s = ChangeLiveSession(c, id, state, at_us, reason, fence); !s.ok()) return s;
    Status s = RunSql(
        c,
        "INSERT INTO trial_metrics(session_id, completed, completion_time_s, task_error, "
        "peak_force_n, time_over_force_limit_s, path_length_m, rms_jerk, overload_events, "
        "duration_s, score, raw_score, caps, recorded_us, station_peak_force_n, "
        "station_time_over_limit_s, link_rtt_ms, link_jitter_ms, link_loss_ratio, link_rate_hz, "
        "guided_share, guided_alpha, lumps, lumps_found, false_marks, localisation_error_m, "
        "coverage, mean_force_n, depth_error_m, path_deviation_m, punctures, extra_punctures, "
        "back_wall_breaches, lateral_strain, cut_deviation_max_m, cut_outside_m, torn_length_m, "
        "cut_lifts) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, "
        "?19, ?20, ?21, ?22, ?23, ?24, ?25, ?26, ?27, ?28, ?29, ?30, ?31, ?32, ?33, ?34, ?35, ?36, "
        "?37, ?38)",
        [&](Statement& st) {
          st.Bind(1, id).Bind(2, int64_t{m.completed ? 1 : 0});
          st.Bind(3, m.completion_time).Bind(4, m.task_error).Bind(5, m.peak_force);
          st.Bind(6, m.time_over_force_limit).Bind(7, m.path_length).Bind(8, m.rms_jerk);
          st.Bind(9, int64_t{m.overload_events}).Bind(10, m.duration).Bind(11, m.score);
          st.Bind(12, m.raw_score).Bind(13, int64_t{m.caps}).Bind(14, NowUs());
          st.Bind(15, m.link.station_peak_force).Bind(16, m.link.station_time_over_limit);
          st.Bind(17, m.link.rtt_ms).Bind(18, m.link.jitter_ms).Bind(19, m.link.loss);
          st.Bind(20, m.link.rate_hz).Bind(21, m.guided_share).Bind(22, m.guided_alpha);
          st.Bind(23, int64_t{m.lumps}).Bind(24, int64_t{m.lumps_found});
          st.Bind(25, int64_t{m.false_marks}).Bind(26, m.localisation_error);
          st.Bind(27, m.coverage).Bind(28, m.mean_force).Bind(29, m.depth_error);
          st.Bind(30, m.path_deviation).Bind(31, int64_t{m.punctures});
          st.Bind(32, int64_t{m.extra_punctures}).Bind(33, int64_t{m.back_wall_breaches});
          st.Bind(34, m.lateral_strain).Bind(35, m.cut_deviation_max).Bind(36, m.cut_outside);
          st.Bind(37, m.torn_length).Bind(38, int64_t{m.cut_lifts});
        });
    if (!s.ok() || trace_json.empty()) return s;
    return RunSql(c, "INSERT INTO session_traces(session_id, trace_json) VALUES (?1, ?2)",
                  [&](Statement& st) { st.Bind(1, id).Bind(2, trace_json); });
  });
}

Status Store::MoveSession(int64_t id, const SessionFence& from, const SessionFence& to,
                          const std::string& placement) {
  if (from.node.empty() || to.node.empty() || from.node == to.node)
    return InvalidArgument("node", "a session moves from one simulation node to another");
  return Write([=](Connection& c) -> Status {
    auto owner = SessionOwner(c, id);
    if (!owner.ok()) return owner.error();
    if (owner->first != from.node || owner->second != from.epoch)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(id) + " belongs to epoch " +
                       std::to_string(owner->second) + " of node '" + owner->first +
                       "', not to epoch " + std::to_string(from.epoch) + " of '" + from.node +
                       "': move refused",
                   "epoch"};
    if (Status f = HoldFence(c, from.node, from.epoch); !f.ok()) return f;
    if (Status f = HoldFence(c, to.node, to.epoch); !f.ok()) return f;
    if (Status p = EndPlacement(c, placement); !p.ok()) return p;
    Status s = RunSql(c,
                      "UPDATE sessions SET node = ?2, epoch = ?3 WHERE id = ?1 AND state IN "
                      "(?4, ?5, ?6)",
                      [&](Statement& st) {
                        st.Bind(1, id).Bind(2, to.node).Bind(3, to.epoch);
                        BindLiveStates(st, 4);
                      });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(id) + " has ended: it does not move", "session"};
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

namespace {

Status CheckNodeRecord(const NodeRecord& n) {
  if (n.name.empty() || n.name.size() > 64)
    return InvalidArgument("name", "a node name of 1 to 64 characters is required");
  if (n.instance.empty() || n.instance.size() > 64)
    return InvalidArgument("instance", "a node instance of 1 to 64 characters is required");
  if (n.grpc_address.empty() || n.grpc_address.size() > 256 || n.udp_host.empty() ||
      n.udp_host.size() > 256)
    return InvalidArgument("address", "the node's addresses are required (at most 256 characters)");
  if (n.udp_port < 1 || n.udp_port > 65535)
    return InvalidArgument("udp_port", "must be within 1..65535");
  if (n.capacity < 0 || n.capacity > 4096 || n.sessions < 0 || n.sessions > 1'000'000)
    return InvalidArgument("capacity", "capacity within 0..4096 and a session count ≥ 0");
  if (!std::isfinite(n.cpu) || n.cpu < 0 || n.cpu > 4096)
    return InvalidArgument("cpu", "must be a finite number of cores ≥ 0");
  return Status::Ok();
}

// The load a heartbeat reports, bound at ?3..?11 of a statement on the nodes row.
void BindNodeLoad(Statement& q, const NodeRecord& n) {
  q.Bind(3, n.grpc_address).Bind(4, n.udp_host).Bind(5, int64_t{n.udp_port});
  q.Bind(6, int64_t{n.capacity}).Bind(7, int64_t{n.sessions}).Bind(8, n.cpu);
  q.Bind(9, int64_t{n.draining ? 1 : 0}).Bind(10, n.started_us).Bind(11, n.heartbeat_us);
}

}  // namespace

Expected<NodeLease> Store::AcquireNode(const NodeRecord& n, int64_t lease_us,
                                       const std::string& reason) {
  if (Status s = CheckNodeRecord(n); !s.ok()) return s.error();
  NodeLease lease;
  Status s = Write([&](Connection& c) -> Status {
    // A new name starts at epoch 0 (taken by the UPDATE below, like any other).
    Status st = RunSql(c,
                       "INSERT INTO nodes(name, grpc_address, udp_host, udp_port, capacity, "
                       "sessions, cpu, draining, down, started_us, heartbeat_us, epoch, instance) "
                       "VALUES (?1, ?3, ?4, ?5, ?6, ?7, ?8, ?9, 1, ?10, ?11, 0, ?2) "
                       "ON CONFLICT(name) DO NOTHING",
                       [&](Statement& q) {
                         q.Bind(1, n.name).Bind(2, n.instance);
                         BindNodeLoad(q, n);
                       });
    if (!st.ok()) return st;
    if (st = NodeRowForUpdate(c, n.name); !st.ok()) return st;
    // Taken when it is down, already ours, or its holder's lease lapsed. PostgreSQL re-checks the
    // condition on the row's newest version after waiting for its lock, so two processes
    // starting under one name cannot both take it.
    st = RunSql(c,
                "UPDATE nodes SET grpc_address = ?3, udp_host = ?4, udp_port = ?5, capacity = ?6, "
                "sessions = ?7, cpu = ?8, draining = ?9, started_us = ?10, heartbeat_us = ?11, "
                "down = 0, epoch = epoch + 1, instance = ?2 "
                "WHERE name = ?1 AND (down = 1 OR instance = ?2 OR heartbeat_us < ?12)",
                [&](Statement& q) {
                  q.Bind(1, n.name).Bind(2, n.instance);
                  BindNodeLoad(q, n);
                  q.Bind(12, n.heartbeat_us - lease_us);
                });
    if (!st.ok()) return st;
    auto q = c.Prepare(
        "SELECT epoch, instance, grpc_address, heartbeat_us FROM nodes "
        "WHERE name = ?1");
    if (!q.ok()) return q.error();
    (*q)->Bind(1, n.name);
    auto row = (*q)->Step();
    if (!row.ok()) return row.error();
    if (!*row) {
      (*q)->Reset();
      return Error{ErrorCode::kIoError, "node " + n.name + " vanished while acquired", "name"};
    }
    const int64_t epoch = (*q)->Int(0);
    const std::string holder = (*q)->String(1), address = (*q)->String(2);
    const int64_t beat = (*q)->Int(3);
    (*q)->Reset();
    if (holder != n.instance)
      return Error{ErrorCode::kAlreadyExists,
                   "node name '" + n.name + "' is held by another live process (instance " +
                       holder + " at " + address + ", its lease renewed " +
                       std::to_string((n.heartbeat_us - beat) / 1000) +
                       " ms ago); stop it first, or give this one another --node-name",
                   "name"};
    lease.epoch = epoch;
    st = RunSql(c,
                "UPDATE sessions SET state = ?3, ended_us = ?1, end_reason = ?2 "
                "WHERE node = ?4 AND epoch < ?5 AND state IN (?6, ?7, ?8)",
                [&](Statement& u) {
                  u.Bind(1, n.heartbeat_us).Bind(2, reason);
                  u.Bind(3, SessionStateName(SessionState::kAborted)).Bind(4, n.name);
                  u.Bind(5, epoch);
                  BindLiveStates(u, 6);
                });
    if (!st.ok()) return st;
    lease.aborted = c.Changes();
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return lease;
}

Status Store::BeatNode(const NodeRecord& n) {
  if (Status s = CheckNodeRecord(n); !s.ok()) return s;
  // One UPDATE, a transaction by itself: one round trip to a shared store (Pending::alone).
  return impl_->WriteAlone([n](Connection& c) -> Status {
    Status st = RunSql(c,
                       "UPDATE nodes SET grpc_address = ?3, udp_host = ?4, udp_port = ?5, "
                       "capacity = ?6, sessions = ?7, cpu = ?8, draining = ?9, started_us = ?10, "
                       "heartbeat_us = ?11 "
                       "WHERE name = ?1 AND instance = ?2 AND epoch = ?12 AND down = 0",
                       [&](Statement& q) {
                         q.Bind(1, n.name).Bind(2, n.instance);
                         BindNodeLoad(q, n);
                         q.Bind(12, n.epoch);
                       });
    if (st.ok() && c.Changes() == 0)
      return Error{ErrorCode::kFailedPrecondition,
                   "node " + n.name + " lost its lease of epoch " + std::to_string(n.epoch) +
                       " (marked down, or its name taken by a newer process)",
                   "epoch"};
    return st;
  });
}

Expected<std::vector<NodeRecord>> Store::ListNodes() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT name, grpc_address, udp_host, udp_port, capacity, sessions, cpu, draining, down, "
      "started_us, heartbeat_us, instance, epoch FROM nodes ORDER BY name");
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
    n.instance = q.String(11);
    n.epoch = q.Int(12);
  }
  (*st)->Reset();
  return out;
}

Expected<std::optional<int>> Store::MarkNodeDown(const std::string& name, int64_t silent_since_us,
                                                 int64_t at_us, const std::string& reason) {
  std::optional<int> aborted;
  Status s = Write([&](Connection& c) -> Status {
    // Only the first to see the silence marks it, and only if no heartbeat came meanwhile.
    if (Status l = NodeRowForUpdate(c, name); !l.ok()) return l;
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
  auto st = (**r).Prepare(std::string("SELECT ") + kTrialMetricColumns +
                          " FROM trial_metrics WHERE session_id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, session_id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  std::optional<scoring::TrialMetrics> out;
  if (*row) out = ReadTrialMetrics(**st, 0);
  (*st)->Reset();
  return out;
}

Expected<std::string> Store::GetSessionTrace(int64_t session_id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT trace_json FROM session_traces WHERE session_id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, session_id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row)
    return Error{ErrorCode::kNotFound,
                 "session " + std::to_string(session_id) + " has no record (it was never driven)",
                 "id"};
  std::string out = (*st)->String(0);
  (*st)->Reset();
  return out;
}

Expected<SessionPage> Store::FindSessions(const SessionQuery& q) {
  if (q.limit < 1 || q.limit > 200) return InvalidArgument("limit", "must be within 1..200");
  if (q.offset < 0) return InvalidArgument("offset", "must not be negative");
  // Names hold no control characters, so a search for one finds nothing; SQLite would cut the
  // pattern at a NUL (and match every row) and PostgreSQL refuses text with one.
  for (const auto* text : {&q.search, &q.trainee, &q.scene})
    if (*text && std::any_of((*text)->begin(), (*text)->end(),
                             [](char c) { return static_cast<unsigned char>(c) < 0x20; }))
      return SessionPage{};
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  // One WHERE for the page and its count; each filter is off when its parameter is NULL.
  const std::string where =
      "WHERE (CAST(?1 AS TEXT) IS NULL OR t.name = ?1) "
      "AND (CAST(?2 AS TEXT) IS NULL OR s.scene = ?2) "
      "AND (CAST(?3 AS BIGINT) IS NULL OR s.created_us >= ?3) "
      "AND (CAST(?4 AS BIGINT) IS NULL OR s.created_us < ?4) "
      "AND (CAST(?5 AS DOUBLE PRECISION) IS NULL OR m.score >= ?5) "
      "AND (CAST(?6 AS DOUBLE PRECISION) IS NULL OR m.score <= ?6) "
      "AND (?7 = 0 OR s.state NOT IN (?8, ?9, ?10)) "
      "AND (CAST(?11 AS TEXT) IS NULL OR t.name LIKE ?11 ESCAPE '!' OR s.scene LIKE ?11 ESCAPE "
      "'!') ";
  auto bind = [&](Statement& st) {
    st.BindOrNull(1, q.trainee).BindOrNull(2, q.scene);
    st.BindOrNull(3, q.from_us).BindOrNull(4, q.to_us);
    st.BindOrNull(5, q.min_score).BindOrNull(6, q.max_score);
    st.Bind(7, int64_t{q.ended_only ? 1 : 0});
    BindLiveStates(st, 8);
    if (q.search) {  // a LIKE pattern matching the text literally anywhere in the name
      std::string pattern = "%";
      for (char c : *q.search) {
        if (c == '%' || c == '_' || c == '!') pattern += '!';
        pattern += c;
      }
      st.Bind(11, pattern + "%");
    } else {
      st.BindNull(11);
    }
  };
  const std::string from =
      "FROM sessions s JOIN trainees t ON t.id = s.trainee_id "
      "LEFT JOIN trial_metrics m ON m.session_id = s.id ";
  SessionPage page;
  {
    auto st = (**r).Prepare("SELECT count(*) " + from + where);
    if (!st.ok()) return st.error();
    bind(**st);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    page.total = *row ? (*st)->Int(0) : 0;
    (*st)->Reset();
  }
  auto st = (**r).Prepare(
      "SELECT s.id, t.name, s.scene, s.state, s.created_us, s.started_us, s.ended_us, "
      "s.end_reason, s.node, m.score, m.completed, "
      "CASE WHEN EXISTS (SELECT 1 FROM session_traces x WHERE x.session_id = s.id) THEN 1 "
      "ELSE 0 END " +
      from + where + "ORDER BY s.created_us DESC, s.id DESC LIMIT ?12 OFFSET ?13");
  if (!st.ok()) return st.error();
  bind(**st);
  (*st)->Bind(12, int64_t{q.limit}).Bind(13, int64_t{q.offset});
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    SessionRow& out = page.rows.emplace_back();
    ReadSession(**st, out.record);
    if (!(*st)->IsNull(9)) out.score = (*st)->Double(9);
    out.completed = !(*st)->IsNull(10) && (*st)->Int(10) != 0;
    out.has_trace = (*st)->Int(11) != 0;
  }
  (*st)->Reset();
  return page;
}

}  // namespace vsurg::db
