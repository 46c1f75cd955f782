#include "db/store.h"

#include <openssl/rand.h>
#include <openssl/sha.h>
#include <sqlite3.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <ctime>
#include <deque>
#include <future>
#include <mutex>
#include <thread>

#include "common/core/csv.h"
#include "db/migrations.h"
#include "db/sqlite.h"

namespace vsurg::db {
namespace {

constexpr const char* kRoleNames[] = {"trainee", "instructor", "evaluator", "admin"};
constexpr const char* kSubjectKinds[] = {"session", "trainee", "model"};
constexpr const char* kEvaluatorGroups[] = {"intern", "associate_chief", "chief"};
constexpr const char* kIndexNames[kIndexes] = {
    "effectiveness", "force_feedback", "real_time", "stability", "deformation_efficiency",
    "fidelity",      "visual_fluency", "immersion", "texture"};

bool IsEvaluatorGroup(std::string_view g) {
  for (const char* n : kEvaluatorGroups)
    if (g == n) return true;
  return false;
}

std::array<unsigned char, SHA256_DIGEST_LENGTH> TokenHash(std::string_view token) {
  std::array<unsigned char, SHA256_DIGEST_LENGTH> h{};
  SHA256(reinterpret_cast<const unsigned char*>(token.data()), token.size(), h.data());
  return h;
}

Expected<std::string> NewToken() {
  unsigned char raw[32];
  if (RAND_bytes(raw, sizeof raw) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "token"};
  static const char* kHex = "0123456789abcdef";
  std::string t = "vst_";
  for (unsigned char b : raw) {
    t.push_back(kHex[b >> 4]);
    t.push_back(kHex[b & 15]);
  }
  return t;
}

// Runs a prepared statement with binds; convenience for the many one-shot writes.
template <class Bind>
Status RunSql(Connection& c, const std::string& sql, Bind&& bind) {
  auto st = c.Prepare(sql);
  if (!st.ok()) return st.error();
  bind(**st);
  return (*st)->Run();
}

Expected<std::optional<int64_t>> LookupId(Connection& c, const std::string& sql,
                                          std::string_view key) {
  auto st = c.Prepare(sql);
  if (!st.ok()) return st.error();
  (*st)->Bind(1, key);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  std::optional<int64_t> id;
  if (*row) id = (*st)->Int(0);
  (*st)->Reset();
  return id;
}

std::string JsonEscape(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 2);
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out.push_back(ch);
        }
    }
  }
  return out;
}

}  // namespace

const char* RoleName(Role r) {
  return kRoleNames[static_cast<int>(r)];
}
std::optional<Role> ParseRole(std::string_view name) {
  for (int i = 0; i < 4; ++i)
    if (name == kRoleNames[i]) return static_cast<Role>(i);
  return std::nullopt;
}
const char* SubjectKindName(SubjectKind k) {
  return kSubjectKinds[static_cast<int>(k)];
}
std::optional<SubjectKind> ParseSubjectKind(std::string_view name) {
  for (int i = 0; i < 3; ++i)
    if (name == kSubjectKinds[i]) return static_cast<SubjectKind>(i);
  return std::nullopt;
}
std::optional<ExportFormat> ParseExportFormat(std::string_view name) {
  if (name == "csv") return ExportFormat::kCsv;
  if (name == "jsonl") return ExportFormat::kJsonLines;
  if (name == "xapi") return ExportFormat::kXapi;
  return std::nullopt;
}

int64_t NowUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string IsoTimeUtc(int64_t us) {
  const int64_t secs = us >= 0 ? us / 1000000 : (us - 999999) / 1000000;
  const auto frac = static_cast<int>(us - secs * 1000000);
  const std::time_t t = static_cast<std::time_t>(secs);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%06dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, frac);
  return buf;
}

struct Store::Impl {
  struct Pending {
    Job job;
    std::function<void(Status)> done;
  };

  StoreOptions options;
  std::unique_ptr<Connection> writer;  // writer thread only (after Open)
  std::mutex queue_mutex;
  std::condition_variable queue_cv;
  std::deque<Pending> queue;
  bool stopping = false;
  std::thread thread;

  std::mutex pool_mutex;
  std::vector<std::unique_ptr<Connection>> pool;

  mutable std::mutex stats_mutex;
  StoreStats stats;

  void WriterLoop();
  void RunBatch(std::vector<Pending>& batch);

  // A pooled read connection, returned on scope exit.
  struct Reader {
    Impl* impl;
    std::unique_ptr<Connection> c;
    Reader(Impl* i, std::unique_ptr<Connection> conn) : impl(i), c(std::move(conn)) {}
    Reader(Reader&& o) noexcept : impl(o.impl), c(std::move(o.c)) {}
    Reader& operator=(Reader&&) = delete;
    ~Reader() {
      if (c) {
        std::lock_guard lock(impl->pool_mutex);
        impl->pool.push_back(std::move(c));
      }
    }
    Connection& operator*() { return *c; }
  };
  Expected<Reader> Read() {
    {
      std::lock_guard lock(pool_mutex);
      if (!pool.empty()) {
        Reader r{this, std::move(pool.back())};
        pool.pop_back();
        return r;
      }
    }
    auto c = Connection::Open(options.path, Connection::Mode::kReadOnly, options.busy_timeout_ms);
    if (!c.ok()) return c.error();
    return Reader{this, std::move(c).value()};
  }
};

void Store::Impl::WriterLoop() {
  std::vector<Pending> batch;
  for (;;) {
    {
      std::unique_lock lock(queue_mutex);
      queue_cv.wait(lock, [&] { return stopping || !queue.empty(); });
      if (queue.empty()) return;  // stopping and drained
      while (!queue.empty() && static_cast<int>(batch.size()) < options.max_batch) {
        batch.push_back(std::move(queue.front()));
        queue.pop_front();
      }
    }
    RunBatch(batch);
    batch.clear();
  }
}

void Store::Impl::RunBatch(std::vector<Pending>& batch) {
  std::vector<Status> results(batch.size());
  Status begin = writer->Exec("BEGIN IMMEDIATE");
  uint64_t failed = 0;
  if (!begin.ok()) {
    for (auto& r : results) r = begin;
    failed = batch.size();
  } else {
    for (size_t i = 0; i < batch.size(); ++i) {
      Status s = writer->Exec("SAVEPOINT job");
      if (s.ok()) {
        s = batch[i].job(*writer);
        if (!s.ok()) {
          (void)writer->Exec("ROLLBACK TO job");
          ++failed;
        }
        (void)writer->Exec("RELEASE job");
      }
      results[i] = std::move(s);
    }
    if (Status commit = writer->Exec("COMMIT"); !commit.ok()) {
      (void)writer->Exec("ROLLBACK");
      for (auto& r : results)
        if (r.ok()) r = commit, ++failed;
    }
  }
  {
    std::lock_guard lock(stats_mutex);
    ++stats.commits;
    stats.jobs += batch.size();
    stats.failed_jobs += failed;
  }
  // Only now, after the COMMIT (fsync), is anything acknowledged.
  for (size_t i = 0; i < batch.size(); ++i)
    if (batch[i].done) batch[i].done(std::move(results[i]));
}

Store::Store(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Store::~Store() {
  {
    std::lock_guard lock(impl_->queue_mutex);
    impl_->stopping = true;
  }
  impl_->queue_cv.notify_all();
  if (impl_->thread.joinable()) impl_->thread.join();
}

int Store::SchemaVersion() {
  return static_cast<int>(Migrations().size());
}

Expected<std::unique_ptr<Store>> Store::Open(const StoreOptions& options) {
  if (options.path.empty()) return InvalidArgument("path", "a database file is required");
  if (options.max_batch < 1 || options.read_connections < 1)
    return InvalidArgument("max_batch", "batch and pool sizes must be >= 1");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  auto writer =
      Connection::Open(options.path, Connection::Mode::kReadWrite, options.busy_timeout_ms);
  if (!writer.ok()) return writer.error();
  impl->writer = std::move(writer).value();
  if (Status s = Migrate(*impl->writer); !s.ok()) return s.error();
  std::unique_ptr<Store> store(new Store(std::move(impl)));
  store->impl_->thread = std::thread([s = store->impl_.get()] { s->WriterLoop(); });
  return store;
}

void Store::WriteAsync(Job job, std::function<void(Status)> done) {
  {
    std::lock_guard lock(impl_->queue_mutex);
    if (impl_->stopping) {
      if (done) done(Error{ErrorCode::kUnavailable, "the store is shutting down", ""});
      return;
    }
    impl_->queue.push_back({std::move(job), std::move(done)});
  }
  impl_->queue_cv.notify_one();
}

Status Store::Write(Job job) {
  std::promise<Status> p;
  auto f = p.get_future();
  WriteAsync(std::move(job), [&p](Status s) { p.set_value(std::move(s)); });
  return f.get();
}

StoreStats Store::stats() const {
  std::lock_guard lock(impl_->stats_mutex);
  return impl_->stats;
}

// --- users and tokens ---

namespace {

Status InsertUser(Connection& c, const std::string& name, Role role, const std::string& group,
                  int64_t& id_out) {
  if (name.empty() || name.size() > 128)
    return InvalidArgument("name", "a user name of 1 to 128 characters is required");
  if (role == Role::kEvaluator && !IsEvaluatorGroup(group))
    return InvalidArgument("group", "an evaluator's group is intern, associate_chief or chief");
  const int64_t now = NowUs();
  Status s = RunSql(c, "INSERT INTO users(name, role, created_us) VALUES (?1, ?2, ?3)",
                    [&](Statement& st) { st.Bind(1, name).Bind(2, RoleName(role)).Bind(3, now); });
  if (!s.ok()) {
    if (s.error().code == ErrorCode::kAlreadyExists)
      return Error{ErrorCode::kAlreadyExists, "user '" + name + "' exists", "name"};
    return s;
  }
  id_out = c.LastInsertId();
  if (role == Role::kTrainee) {
    // A trainee known from earlier sessions or imports gets linked to the new login.
    s = RunSql(c,
               "INSERT INTO trainees(name, trainee_group, user_id) VALUES (?1, ?2, ?3) "
               "ON CONFLICT(name) DO UPDATE SET user_id = excluded.user_id, "
               "trainee_group = excluded.trainee_group",
               [&](Statement& st) { st.Bind(1, name).Bind(2, group).Bind(3, id_out); });
  } else if (role == Role::kEvaluator) {
    s = RunSql(c,
               "INSERT INTO evaluators(name, evaluator_group, user_id) VALUES (?1, ?2, ?3) "
               "ON CONFLICT(name) DO UPDATE SET user_id = excluded.user_id",
               [&](Statement& st) { st.Bind(1, name).Bind(2, group).Bind(3, id_out); });
  }
  return s;
}

Status InsertToken(Connection& c, int64_t user_id, const std::string& token,
                   const std::string& label) {
  const auto h = TokenHash(token);
  return RunSql(c, "INSERT INTO tokens(user_id, hash, label, created_us) VALUES (?1, ?2, ?3, ?4)",
                [&](Statement& st) {
                  st.Bind(1, user_id).BindBlob(2, h.data(), static_cast<int>(h.size()));
                  st.Bind(3, label).Bind(4, NowUs());
                });
}

}  // namespace

Expected<UserRecord> Store::CreateUser(const std::string& name, Role role,
                                       const std::string& group) {
  UserRecord u;
  Status s = Write([&](Connection& c) { return InsertUser(c, name, role, group, u.id); });
  if (!s.ok()) return s.error();
  u.name = name;
  u.role = role;
  u.group = group;
  u.created_us = NowUs();
  return u;
}

Status Store::SetUserDisabled(const std::string& name, bool disabled) {
  return Write([&](Connection& c) -> Status {
    Status s = RunSql(c, "UPDATE users SET disabled = ?2 WHERE name = ?1",
                      [&](Statement& st) { st.Bind(1, name).Bind(2, int64_t{disabled ? 1 : 0}); });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no user '" + name + "'", "name"};
    return s;
  });
}

Expected<std::string> Store::IssueToken(const std::string& user, const std::string& label) {
  auto token = NewToken();
  if (!token.ok()) return token.error();
  Status s = Write([&](Connection& c) -> Status {
    auto id = LookupId(c, "SELECT id FROM users WHERE name = ?1", user);
    if (!id.ok()) return id.error();
    if (!*id) return Error{ErrorCode::kNotFound, "no user '" + user + "'", "user"};
    return InsertToken(c, **id, *token, label);
  });
  if (!s.ok()) return s.error();
  return token;
}

Status Store::RevokeTokens(const std::string& user) {
  return Write([&](Connection& c) -> Status {
    auto id = LookupId(c, "SELECT id FROM users WHERE name = ?1", user);
    if (!id.ok()) return id.error();
    if (!*id) return Error{ErrorCode::kNotFound, "no user '" + user + "'", "user"};
    return RunSql(c, "UPDATE tokens SET revoked = 1 WHERE user_id = ?1",
                  [&](Statement& st) { st.Bind(1, **id); });
  });
}

Expected<std::string> Store::InitAdmin(const std::string& name) {
  auto token = NewToken();
  if (!token.ok()) return token.error();
  Status s = Write([&](Connection& c) -> Status {
    auto any = LookupId(c, "SELECT id FROM users WHERE role = ?1 LIMIT 1", "admin");
    if (!any.ok()) return any.error();
    if (*any)
      return Error{ErrorCode::kAlreadyExists,
                   "an administrator exists already; ask them for a token", "init"};
    int64_t id = 0;
    if (Status st = InsertUser(c, name, Role::kAdmin, "", id); !st.ok()) return st;
    return InsertToken(c, id, *token, "init");
  });
  if (!s.ok()) return s.error();
  return token;
}

Expected<Principal> Store::Authenticate(std::string_view token) {
  if (token.size() < 8 || token.size() > 256)
    return Error{ErrorCode::kUnauthenticated, "malformed token", "authorization"};
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  const auto h = TokenHash(token);
  auto st = (**r).Prepare(
      "SELECT u.id, u.name, u.role, u.disabled, t.revoked, "
      "coalesce(tr.trainee_group, ev.evaluator_group, '') FROM tokens t "
      "JOIN users u ON u.id = t.user_id LEFT JOIN trainees tr ON tr.user_id = u.id "
      "LEFT JOIN evaluators ev ON ev.user_id = u.id WHERE t.hash = ?1");
  if (!st.ok()) return st.error();
  (*st)->BindBlob(1, h.data(), static_cast<int>(h.size()));
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kUnauthenticated, "unknown token", "authorization"};
  }
  Principal p;
  p.user_id = (*st)->Int(0);
  p.name = (*st)->String(1);
  p.role = ParseRole((*st)->Text(2)).value_or(Role::kTrainee);
  const bool disabled = (*st)->Int(3) != 0, revoked = (*st)->Int(4) != 0;
  p.group = (*st)->String(5);
  (*st)->Reset();
  if (revoked) return Error{ErrorCode::kUnauthenticated, "the token was revoked", "authorization"};
  if (disabled) return Error{ErrorCode::kUnauthenticated, "the user is disabled", "authorization"};
  return p;
}

Expected<std::vector<UserRecord>> Store::ListUsers() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT u.id, u.name, u.role, coalesce(tr.trainee_group, ev.evaluator_group, ''), "
      "u.created_us, u.disabled FROM users u LEFT JOIN trainees tr ON tr.user_id = u.id "
      "LEFT JOIN evaluators ev ON ev.user_id = u.id ORDER BY u.id");
  if (!st.ok()) return st.error();
  std::vector<UserRecord> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    UserRecord u;
    u.id = (*st)->Int(0);
    u.name = (*st)->String(1);
    u.role = ParseRole((*st)->Text(2)).value_or(Role::kTrainee);
    u.group = (*st)->String(3);
    u.created_us = (*st)->Int(4);
    u.disabled = (*st)->Int(5) != 0;
    out.push_back(std::move(u));
  }
  (*st)->Reset();
  return out;
}

// --- sessions ---

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
  s.state = st.String(3);
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
  rec.state = "created";
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
                "VALUES (?1, ?2, 'created', ?3)",
                [&](Statement& q) { q.Bind(1, *tid).Bind(2, scene).Bind(3, rec.created_us); });
    rec.id = c.LastInsertId();
    return st;
  });
  if (!s.ok()) return s.error();
  return rec;
}

Status Store::SetSessionState(int64_t id, const std::string& state, int64_t at_us,
                              const std::string& reason) {
  return Write([=](Connection& c) -> Status {
    Status s = RunSql(
        c,
        "UPDATE sessions SET state = ?2, "
        "started_us = CASE WHEN ?2 = 'running' AND started_us IS NULL THEN ?3 "
        "ELSE started_us END, "
        "ended_us = CASE WHEN ?2 IN ('ended', 'disconnected', 'aborted') THEN ?3 "
        "ELSE ended_us END, "
        "end_reason = CASE WHEN ?4 <> '' THEN ?4 ELSE end_reason END "
        "WHERE id = ?1",
        [&](Statement& st) { st.Bind(1, id).Bind(2, state).Bind(3, at_us).Bind(4, reason); });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no session " + std::to_string(id), "session"};
    return s;
  });
}

Expected<int> Store::AbortOrphanedSessions(int64_t at_us, const std::string& reason) {
  int changed = 0;
  Status s = Write([=, &changed](Connection& c) -> Status {
    Status st = RunSql(c,
                       "UPDATE sessions SET state = 'aborted', ended_us = ?1, end_reason = ?2 "
                       "WHERE state IN ('created', 'running', 'stalled')",
                       [&](Statement& q) { q.Bind(1, at_us).Bind(2, reason); });
    if (st.ok()) changed = c.Changes();
    return st;
  });
  if (!s.ok()) return s.error();
  return changed;
}

Status Store::RecordTrialMetrics(int64_t session_id, const TrialMetricsRecord& m) {
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
          st.Bind(3, m.completion_time_s).Bind(4, m.task_error).Bind(5, m.peak_force_n);
          st.Bind(6, m.time_over_force_limit_s).Bind(7, m.path_length_m).Bind(8, m.rms_jerk);
          st.Bind(9, int64_t{m.overload_events}).Bind(10, m.duration_s).Bind(11, m.score);
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
                          "WHERE (?1 IS NULL OR t.name = ?1) ORDER BY s.id");
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

Expected<std::optional<TrialMetricsRecord>> Store::GetTrialMetrics(int64_t session_id) {
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
  std::optional<TrialMetricsRecord> out;
  if (*row) {
    Statement& q = **st;
    TrialMetricsRecord m;
    m.completed = q.Int(0) != 0;
    m.completion_time_s = q.Double(1);
    m.task_error = q.Double(2);
    m.peak_force_n = q.Double(3);
    m.time_over_force_limit_s = q.Double(4);
    m.path_length_m = q.Double(5);
    m.rms_jerk = q.Double(6);
    m.overload_events = static_cast<int>(q.Int(7));
    m.duration_s = q.Double(8);
    m.score = q.Double(9);
    m.raw_score = q.Double(10);
    m.caps = static_cast<uint32_t>(q.Int(11));
    out = m;
  }
  (*st)->Reset();
  return out;
}

// --- evaluations ---

namespace {

Status ValidateSubmission(const Submission& s) {
  if (s.idempotency_key.empty() || s.idempotency_key.size() > 128)
    return InvalidArgument("idempotency_key", "1 to 128 characters are required");
  if (s.evaluator.empty() || s.evaluator.size() > 128)
    return InvalidArgument("evaluator", "an evaluator name of 1 to 128 characters is required");
  if (!IsEvaluatorGroup(s.evaluator_group))
    return InvalidArgument("evaluator_group", "unknown group '" + s.evaluator_group +
                                                  "' (intern, associate_chief or chief)");
  if (s.subject.empty() || s.subject.size() > 256)
    return InvalidArgument("subject", "a subject of 1 to 256 characters is required");
  if (s.moment_min && (!std::isfinite(*s.moment_min) || *s.moment_min < 0))
    return InvalidArgument("moment_min", "must be finite and >= 0 minutes");
  for (int j = 0; j < kIndexes; ++j)
    if (!std::isfinite(s.scores[j]) || s.scores[j] < 0 || s.scores[j] > 10)
      return InvalidArgument("scores[" + std::to_string(j) + "]",
                             std::string(kIndexNames[j]) + " score must be within 0..10");
  return Status::Ok();
}

// What differs between a stored submission and a retry that reuses its key, or "" when the
// retry is the identical submission (only then is it a duplicate).
std::string SubmissionDifference(Connection& c, int64_t id, const Submission& s) {
  auto st = c.Prepare(
      "SELECT e.name, s.evaluator_group, s.subject_kind, s.subject, s.moment_min FROM submissions "
      "s JOIN evaluators e ON e.id = s.evaluator_id WHERE s.id = ?1");
  if (!st.ok()) return "it cannot be read back";
  (*st)->Bind(1, id);
  auto row = (*st)->Step();
  if (!row.ok() || !*row) return (*st)->Reset(), "it cannot be read back";
  std::string diff;
  if ((*st)->Text(0) != s.evaluator)
    diff = "the evaluator";
  else if ((*st)->Text(1) != s.evaluator_group)
    diff = "the evaluator group";
  else if ((*st)->Text(2) != SubjectKindName(s.subject_kind) || (*st)->Text(3) != s.subject)
    diff = "the subject";
  else if ((*st)->IsNull(4) != !s.moment_min || (s.moment_min && (*st)->Double(4) != *s.moment_min))
    diff = "the training moment";
  (*st)->Reset();
  if (!diff.empty()) return diff;
  auto sc = c.Prepare("SELECT index_no, score FROM evaluations WHERE submission_id = ?1");
  if (!sc.ok()) return "it cannot be read back";
  (*sc)->Bind(1, id);
  for (;;) {
    auto r = (*sc)->Step();
    if (!r.ok()) return (*sc)->Reset(), "it cannot be read back";
    if (!*r) break;
    const int64_t j = (*sc)->Int(0) - 1;
    if (j >= 0 && j < kIndexes && (*sc)->Double(1) != s.scores[j]) {
      diff = std::string("the ") + kIndexNames[j] + " score";
      break;
    }
  }
  (*sc)->Reset();
  return diff;
}

// The body of one submission, inside the writer's savepoint.
Status InsertSubmission(Connection& c, const Submission& s, SubmitResult& out) {
  // A retry: the same key returns the first result, but only for the identical submission; a
  // reused key with another payload is refused, never acknowledged and dropped.
  {
    auto st = c.Prepare("SELECT id, submitted_us FROM submissions WHERE idempotency_key = ?1");
    if (!st.ok()) return st.error();
    (*st)->Bind(1, s.idempotency_key);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (*row) {
      const int64_t id = (*st)->Int(0), at = (*st)->Int(1);
      (*st)->Reset();
      const std::string diff = SubmissionDifference(c, id, s);
      if (!diff.empty())
        return Error{ErrorCode::kAlreadyExists,
                     "idempotency key '" + s.idempotency_key +
                         "' was used for a different submission (" + diff +
                         " differs); stored evaluations are not changed",
                     "idempotency_key"};
      out.submission_id = id;
      out.submitted_us = at;
      out.duplicate = true;
      return Status::Ok();
    }
    (*st)->Reset();
  }
  switch (s.subject_kind) {
    case SubjectKind::kSession: {
      int64_t id = 0;
      const auto r = std::from_chars(s.subject.data(), s.subject.data() + s.subject.size(), id);
      if (r.ec != std::errc() || r.ptr != s.subject.data() + s.subject.size())
        return InvalidArgument("subject", "a session subject is a session id");
      auto found = LookupId(c, "SELECT id FROM sessions WHERE id = CAST(?1 AS INTEGER)", s.subject);
      if (!found.ok()) return found.error();
      if (!*found) return Error{ErrorCode::kNotFound, "no session " + s.subject, "subject"};
      break;
    }
    case SubjectKind::kTrainee: {
      auto found = LookupId(c, "SELECT id FROM trainees WHERE name = ?1", s.subject);
      if (!found.ok()) return found.error();
      if (!*found) return Error{ErrorCode::kNotFound, "no trainee '" + s.subject + "'", "subject"};
      break;
    }
    case SubjectKind::kModel:
      break;
  }
  // The evaluator: created on first sight (imports), and always in one group.
  int64_t evaluator_id = 0;
  {
    auto st = c.Prepare("SELECT id, evaluator_group FROM evaluators WHERE name = ?1");
    if (!st.ok()) return st.error();
    (*st)->Bind(1, s.evaluator);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (*row) {
      evaluator_id = (*st)->Int(0);
      const std::string group = (*st)->String(1);
      (*st)->Reset();
      if (group != s.evaluator_group)
        return InvalidArgument("evaluator_group", "evaluator '" + s.evaluator + "' is in group " +
                                                      group + ", not " + s.evaluator_group);
    } else {
      (*st)->Reset();
      Status ins = RunSql(c, "INSERT INTO evaluators(name, evaluator_group) VALUES (?1, ?2)",
                          [&](Statement& q) { q.Bind(1, s.evaluator).Bind(2, s.evaluator_group); });
      if (!ins.ok()) return ins;
      evaluator_id = c.LastInsertId();
    }
  }
  auto by = LookupId(c, "SELECT id FROM users WHERE name = ?1", s.submitted_by);
  if (!by.ok()) return by.error();
  if (!*by) return Error{ErrorCode::kNotFound, "no user '" + s.submitted_by + "'", "submitted_by"};
  out.submitted_us = NowUs();
  Status ins = RunSql(c,
                      "INSERT INTO submissions(idempotency_key, evaluator_id, evaluator_group, "
                      "subject_kind, subject, moment_min, submitted_us, submitted_by) "
                      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                      [&](Statement& q) {
                        q.Bind(1, s.idempotency_key).Bind(2, evaluator_id);
                        q.Bind(3, s.evaluator_group).Bind(4, SubjectKindName(s.subject_kind));
                        q.Bind(5, s.subject).Bind(6, s.moment_min).Bind(7, out.submitted_us);
                        q.Bind(8, **by);
                      });
  if (!ins.ok()) {
    if (ins.error().code == ErrorCode::kAlreadyExists)
      return Error{ErrorCode::kAlreadyExists,
                   "evaluator '" + s.evaluator + "' has already rated this " +
                       SubjectKindName(s.subject_kind) + (s.moment_min ? " at this moment" : ""),
                   "subject"};
    return ins;
  }
  out.submission_id = c.LastInsertId();
  auto st =
      c.Prepare("INSERT INTO evaluations(submission_id, index_no, score) VALUES (?1, ?2, ?3)");
  if (!st.ok()) return st.error();
  for (int j = 0; j < kIndexes; ++j) {
    (*st)->Bind(1, out.submission_id).Bind(2, int64_t{j + 1}).Bind(3, s.scores[j]);
    if (Status r = (*st)->Run(); !r.ok()) return r;
  }
  return Status::Ok();
}

}  // namespace

namespace {

// Rows ordered by submission then index_no, with the submission id in column 0 and
// (index_no, score) in columns `index_col`, `index_col + 1`: calls `first(q)` at each new
// submission (it appends a record and returns its scores) and fills the nine scores.
template <class First>
Status CollectScores(Statement& q, int index_col, First&& first) {
  int64_t current = -1;
  std::array<double, kIndexes>* scores = nullptr;
  for (;;) {
    auto row = q.Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    if (q.Int(0) != current) {
      current = q.Int(0);
      scores = &first(q);
    }
    const int64_t j = q.Int(index_col);
    if (j >= 1 && j <= kIndexes) (*scores)[j - 1] = q.Double(index_col + 1);
  }
  q.Reset();
  return Status::Ok();
}

}  // namespace

void Store::SubmitEvaluationAsync(Submission s, std::function<void(Expected<SubmitResult>)> done) {
  if (Status v = ValidateSubmission(s); !v.ok()) {
    done(v.error());
    return;
  }
  auto shared = std::make_shared<std::pair<Submission, SubmitResult>>(std::move(s), SubmitResult{});
  WriteAsync([shared](Connection& c) { return InsertSubmission(c, shared->first, shared->second); },
             [shared, done = std::move(done)](Status st) {
               if (!st.ok()) {
                 done(st.error());
               } else {
                 done(shared->second);
               }
             });
}

Expected<SubmitResult> Store::SubmitEvaluation(const Submission& s) {
  std::promise<Expected<SubmitResult>> p;
  auto f = p.get_future();
  SubmitEvaluationAsync(s, [&p](Expected<SubmitResult> r) { p.set_value(std::move(r)); });
  return f.get();
}

Expected<std::vector<RatingRow>> Store::LoadRatings(SubjectKind kind, const std::string& subject) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, e.name, s.evaluator_group, s.moment_min, v.index_no, v.score "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN evaluations v ON v.submission_id = s.id "
      "WHERE s.subject_kind = ?1 AND s.subject = ?2 ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, SubjectKindName(kind)).Bind(2, subject);
  std::vector<RatingRow> out;
  Status s = CollectScores(**st, 4, [&](Statement& q) -> std::array<double, kIndexes>& {
    RatingRow& rr = out.emplace_back();
    rr.evaluator = q.String(1);
    rr.evaluator_group = q.String(2);
    if (!q.IsNull(3)) rr.moment_min = q.Double(3);
    return rr.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<TrainingRow>> Store::LoadTrainingRows() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, s.subject, t.trainee_group, s.moment_min, e.name, v.index_no, v.score "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN trainees t ON t.name = s.subject JOIN evaluations v ON v.submission_id = s.id "
      "WHERE s.subject_kind = 'trainee' AND s.moment_min IS NOT NULL "
      "ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  std::vector<TrainingRow> out;
  Status s = CollectScores(**st, 5, [&](Statement& q) -> std::array<double, kIndexes>& {
    TrainingRow& t = out.emplace_back();
    t.trainee = q.String(1);
    t.trainee_group = q.String(2);
    t.moment_min = q.Double(3);
    t.evaluator = q.String(4);
    return t.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<int64_t> Store::CountEvaluationRows() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT count(*) FROM evaluations");
  if (!st.ok()) return st.error();
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  const int64_t n = (*st)->Int(0);
  (*st)->Reset();
  return n;
}

Status Store::PutWeightSet(const std::string& name, const std::string& json) {
  return Write([=](Connection& c) {
    return RunSql(c,
                  "INSERT INTO weight_sets(name, json, created_us) VALUES (?1, ?2, ?3) "
                  "ON CONFLICT(name) DO UPDATE SET json = excluded.json, "
                  "created_us = excluded.created_us",
                  [&](Statement& st) { st.Bind(1, name).Bind(2, json).Bind(3, NowUs()); });
  });
}

Expected<std::string> Store::GetWeightSet(const std::string& name) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT json FROM weight_sets WHERE name = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, name);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kNotFound, "no weight set '" + name + "'", "weights"};
  }
  std::string json = (*st)->String(0);
  (*st)->Reset();
  return json;
}

Expected<std::vector<std::string>> Store::ListWeightSets() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT name FROM weight_sets ORDER BY name");
  if (!st.ok()) return st.error();
  std::vector<std::string> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    out.push_back((*st)->String(0));
  }
  (*st)->Reset();
  return out;
}

Status Store::RecordReport(const std::string& subject_kind, const std::string& subject,
                           const std::string& weights_json, const std::string& report_json) {
  return Write([=](Connection& c) {
    return RunSql(c,
                  "INSERT INTO reports(subject_kind, subject, weights_json, report_json, "
                  "created_us) VALUES (?1, ?2, ?3, ?4, ?5)",
                  [&](Statement& st) {
                    st.Bind(1, subject_kind).Bind(2, subject).Bind(3, weights_json);
                    st.Bind(4, report_json).Bind(5, NowUs());
                  });
  });
}

// --- export ---

Status Store::Export(const ExportFilter& filter, ExportFormat format,
                     const std::function<bool(std::string_view)>& sink) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  // One read transaction: the export is a consistent snapshot even while writes go on.
  if (Status s = (**r).Exec("BEGIN"); !s.ok()) return s;
  struct EndRead {
    Connection& c;
    ~EndRead() { (void)c.Exec("COMMIT"); }
  } end_read{**r};
  auto st = (**r).Prepare(
      "SELECT s.id, s.submitted_us, e.name, s.evaluator_group, s.subject_kind, s.subject, "
      "s.moment_min, v.index_no, v.score, coalesce(st.name, tt.name, '') "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN evaluations v ON v.submission_id = s.id "
      "LEFT JOIN sessions ss ON s.subject_kind = 'session' AND ss.id = CAST(s.subject AS INTEGER) "
      "LEFT JOIN trainees st ON st.id = ss.trainee_id "
      "LEFT JOIN trainees tt ON s.subject_kind = 'trainee' AND tt.name = s.subject "
      "WHERE (?1 IS NULL OR s.submitted_us >= ?1) AND (?2 IS NULL OR s.submitted_us < ?2) "
      "AND (?3 IS NULL OR coalesce(st.name, tt.name) = ?3) "
      "AND (?4 IS NULL OR (s.subject_kind = 'session' AND s.subject = CAST(?4 AS TEXT))) "
      "ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  Statement& q = **st;
  q.Reset();
  if (filter.from_us) q.Bind(1, *filter.from_us);
  if (filter.to_us) q.Bind(2, *filter.to_us);
  if (filter.trainee) q.Bind(3, *filter.trainee);
  if (filter.session) q.Bind(4, *filter.session);

  std::string buf;
  buf.reserve(1 << 17);
  auto flush = [&](bool force) {
    if (buf.size() >= (1 << 16) || (force && !buf.empty())) {
      const bool more = sink(buf);
      buf.clear();
      return more;
    }
    return true;
  };
  if (format == ExportFormat::kCsv)
    buf +=
        "submission_id,submitted_at,evaluator,evaluator_group,subject_kind,subject,trainee,"
        "moment_min,index_no,index_name,score\r\n";

  // xAPI: one statement per submission, gathered over its nine rows.
  int64_t xapi_id = -1;
  std::string xapi_head;
  std::string xapi_scores;
  double xapi_sum = 0;
  int xapi_n = 0;
  auto xapi_flush = [&] {
    if (xapi_id < 0) return;
    buf += xapi_head;
    buf += ",\"result\":{\"score\":{\"raw\":";
    csv::AppendNumber(buf, xapi_n ? xapi_sum / xapi_n : 0.0);
    buf += ",\"min\":0,\"max\":10},\"extensions\":{\"urn:vsurg:index-scores\":{";
    buf += xapi_scores;
    buf += "}}}}\n";
  };
  char num[32];
  for (;;) {
    auto row = q.Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    const int64_t id = q.Int(0);
    const int64_t at = q.Int(1);
    const std::string_view evaluator = q.Text(2), group = q.Text(3), kind = q.Text(4),
                           subject = q.Text(5), trainee = q.Text(9);
    const bool has_moment = !q.IsNull(6);
    const double moment = has_moment ? q.Double(6) : 0;
    const int64_t index_no = q.Int(7);
    const double score = q.Double(8);
    const char* index_name = index_no >= 1 && index_no <= kIndexes ? kIndexNames[index_no - 1] : "";
    switch (format) {
      case ExportFormat::kCsv: {
        std::snprintf(num, sizeof num, "%lld,", static_cast<long long>(id));
        buf += num;
        buf += IsoTimeUtc(at);
        buf.push_back(',');
        csv::AppendText(buf, evaluator);
        buf.push_back(',');
        buf += group;
        buf.push_back(',');
        buf += kind;
        buf.push_back(',');
        csv::AppendText(buf, subject);
        buf.push_back(',');
        csv::AppendText(buf, trainee);
        buf.push_back(',');
        if (has_moment) csv::AppendNumber(buf, moment);
        std::snprintf(num, sizeof num, ",%lld,", static_cast<long long>(index_no));
        buf += num;
        buf += index_name;
        buf.push_back(',');
        csv::AppendNumber(buf, score);
        buf += "\r\n";
        break;
      }
      case ExportFormat::kJsonLines: {
        std::snprintf(num, sizeof num, "{\"submission_id\":%lld", static_cast<long long>(id));
        buf += num;
        buf += ",\"submitted_at\":\"" + IsoTimeUtc(at) + "\",\"evaluator\":\"";
        buf += JsonEscape(evaluator);
        buf += "\",\"evaluator_group\":\"";
        buf += group;
        buf += "\",\"subject_kind\":\"";
        buf += kind;
        buf += "\",\"subject\":\"";
        buf += JsonEscape(subject);
        buf += "\",\"trainee\":\"";
        buf += JsonEscape(trainee);
        buf += "\",\"moment_min\":";
        if (has_moment) {
          csv::AppendNumber(buf, moment);
        } else {
          buf += "null";
        }
        std::snprintf(num, sizeof num, ",\"index_no\":%lld", static_cast<long long>(index_no));
        buf += num;
        buf += ",\"index_name\":\"";
        buf += index_name;
        buf += "\",\"score\":";
        csv::AppendNumber(buf, score);
        buf += "}\n";
        break;
      }
      case ExportFormat::kXapi: {
        if (id != xapi_id) {
          xapi_flush();
          xapi_id = id;
          xapi_sum = 0;
          xapi_n = 0;
          xapi_scores.clear();
          // actor: the evaluator (an account on this platform); verb: ADL "scored";
          // object: the rated subject as an activity.
          xapi_head = "{\"id\":\"urn:vsurg:submission:" + std::to_string(id) +
                      "\",\"timestamp\":\"" + IsoTimeUtc(at) +
                      "\",\"actor\":{\"objectType\":\"Agent\",\"account\":{\"homePage\":"
                      "\"urn:vsurg\",\"name\":\"" +
                      JsonEscape(evaluator) +
                      "\"}},\"verb\":{\"id\":\"http://adlnet.gov/expapi/verbs/scored\","
                      "\"display\":{\"en-US\":\"scored\"}},\"object\":{\"objectType\":"
                      "\"Activity\",\"id\":\"urn:vsurg:" +
                      std::string(kind) + ":" + JsonEscape(subject) +
                      "\"},\"context\":{\"extensions\":{\"urn:vsurg:evaluator-group\":\"" +
                      std::string(group) + "\"}}";
        }
        if (!xapi_scores.empty()) xapi_scores.push_back(',');
        xapi_scores += "\"";
        xapi_scores += index_name;
        xapi_scores += "\":";
        csv::AppendNumber(xapi_scores, score);
        xapi_sum += score;
        ++xapi_n;
        break;
      }
    }
    if (!flush(false)) {
      q.Reset();
      return Status::Ok();  // the reader went away; nothing to clean up
    }
  }
  q.Reset();
  if (format == ExportFormat::kXapi) xapi_flush();
  flush(true);
  return Status::Ok();
}

Status Store::Backup(const std::string& destination) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  sqlite3* dest = nullptr;
  int rc = sqlite3_open_v2(destination.c_str(), &dest, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE,
                           nullptr);
  if (rc != SQLITE_OK) {
    Error e = SqliteError(dest, rc, "backup to " + destination);
    sqlite3_close(dest);
    return e;
  }
  sqlite3_backup* b = sqlite3_backup_init(dest, "main", (**r).handle(), "main");
  if (!b) {
    Error e = SqliteError(dest, sqlite3_errcode(dest), "backup to " + destination);
    sqlite3_close(dest);
    return e;
  }
  // Copy in steps of 256 pages so writers are not held off for the whole copy.
  do {
    rc = sqlite3_backup_step(b, 256);
    if (rc == SQLITE_BUSY || rc == SQLITE_LOCKED) sqlite3_sleep(5);
  } while (rc == SQLITE_OK || rc == SQLITE_BUSY || rc == SQLITE_LOCKED);
  sqlite3_backup_finish(b);
  Status out = Status::Ok();
  if (rc != SQLITE_DONE) out = SqliteError(dest, rc, "backup to " + destination);
  sqlite3_close(dest);
  return out;
}

Expected<std::string> Store::IntegrityCheck() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("PRAGMA integrity_check");
  if (!st.ok()) return st.error();
  std::string out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    if (!out.empty()) out += "; ";
    out += (*st)->Text(0);
  }
  (*st)->Reset();
  return out;
}

}  // namespace vsurg::db
