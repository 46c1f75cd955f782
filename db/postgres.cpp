#include "db/postgres.h"

#include <libpq-fe.h>

#include <cstdio>
#include <cstdlib>
#include <regex>

namespace vsurg::db {
namespace {

// The store's tables: IntegrityCheck looks for each of them.
constexpr const char* kTables[] = {
    "users",         "tokens",           "trainees",    "evaluators",  "scenes",      "sessions",
    "trial_metrics", "training_moments", "submissions", "evaluations", "weight_sets", "reports"};

// Any number the store's processes agree on: the advisory lock that serialises migrations.
constexpr const char* kSchemaLock = "SELECT pg_advisory_xact_lock(731052811)";
// A reservation is a transient count, not a record: its commit need not wait for the WAL's
// flush (a reservation a crash loses counts no longer than its expiry would have), so the lock is
// held for the statements, not for an fsync. One round trip for both.
constexpr const char* kPlacementLock =
    "SELECT pg_advisory_xact_lock(731052812), set_config('synchronous_commit', 'off', true)";

bool Succeeded(pg_result* r) {
  const auto s = PQresultStatus(r);
  return s == PGRES_COMMAND_OK || s == PGRES_TUPLES_OK;
}

void IgnoreNotice(void*, const char*) {}  // "relation already exists, skipping" and the like

}  // namespace

Error PgError(pg_conn* conn, pg_result* result, std::string_view what) {
  const char* state = result ? PQresultErrorField(result, PG_DIAG_SQLSTATE) : nullptr;
  std::string message = result ? PQresultErrorMessage(result) : "";
  if (message.empty() && conn) message = PQerrorMessage(conn);
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  if (const auto nl = message.find('\n'); nl != std::string::npos) message.resize(nl);
  ErrorCode code = ErrorCode::kIoError;
  const std::string s = state ? state : "";
  if (s == "23505") {
    code = ErrorCode::kAlreadyExists;
  } else if (s.starts_with("23") || s.starts_with("22")) {
    code = ErrorCode::kInvalidArgument;  // integrity constraints, bad data (invalid JSON, …)
  } else if (s.empty() || s.starts_with("08") || s.starts_with("57") || s == "40001" ||
             s == "40P01" || s == "55P03" || (conn && PQstatus(conn) == CONNECTION_BAD)) {
    code = ErrorCode::kUnavailable;  // no answer, shutting down, serialisation, lock timeout
  } else if (s == "25006") {
    code = ErrorCode::kFailedPrecondition;  // a write in a read-only transaction
  }
  return Error{code, std::string(what) + ": " + message, ""};
}

PgStatement::PgStatement(PgConnection* c, std::string name, std::string text, int params,
                         int generation)
    : c_(c),
      name_(std::move(name)),
      text_(std::move(text)),
      generation_(generation),
      values_(static_cast<size_t>(params)),
      formats_(static_cast<size_t>(params), 0) {}

PgStatement::~PgStatement() {
  if (result_) PQclear(result_);
}

void PgStatement::Set(int i, std::string value, int format) {
  if (i < 1 || i > static_cast<int>(values_.size())) return;  // as SQLite: out of range ignored
  values_[i - 1] = std::move(value);
  formats_[i - 1] = format;
}

Statement& PgStatement::Bind(int i, int64_t v) {
  Set(i, std::to_string(v), 0);
  return *this;
}
Statement& PgStatement::Bind(int i, double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);  // round-trips every double
  Set(i, buf, 0);
  return *this;
}
Statement& PgStatement::Bind(int i, std::string_view v) {
  Set(i, std::string(v), 0);
  return *this;
}
Statement& PgStatement::BindBlob(int i, const void* data, int size) {
  Set(i, std::string(static_cast<const char*>(data), static_cast<size_t>(size)), 1);
  return *this;
}
Statement& PgStatement::BindNull(int i) {
  if (i >= 1 && i <= static_cast<int>(values_.size())) values_[i - 1].reset();
  return *this;
}

pg_result* PgStatement::Execute() {
  if (generation_ != c_->generation()) {  // the connection was reset: prepare it again
    c_->CountRoundTrip();
    pg_result* r = PQprepare(c_->handle(), name_.c_str(), text_.c_str(),
                             static_cast<int>(values_.size()), nullptr);
    if (!Succeeded(r)) return r;
    PQclear(r);
    generation_ = c_->generation();
  }
  std::vector<const char*> values(values_.size());
  std::vector<int> lengths(values_.size());
  for (size_t i = 0; i < values_.size(); ++i) {
    values[i] = values_[i] ? values_[i]->data() : nullptr;
    lengths[i] = values_[i] ? static_cast<int>(values_[i]->size()) : 0;
  }
  c_->CountRoundTrip();
  return PQexecPrepared(c_->handle(), name_.c_str(), static_cast<int>(values.size()), values.data(),
                        lengths.data(), formats_.data(), 0);
}

Expected<bool> PgStatement::Step() {
  if (!result_) {
    const bool idle = c_->Idle();
    result_ = Execute();
    // A statement outside a transaction (a read) that met a lost connection runs once more on
    // a new one; inside a transaction the loss fails it (its transaction is gone).
    if (!Succeeded(result_) && idle && PQstatus(c_->handle()) == CONNECTION_BAD &&
        c_->Reconnect()) {
      PQclear(result_);
      result_ = Execute();
    }
    if (!Succeeded(result_)) {
      Error e = PgError(c_->handle(), result_, "step");
      Reset();
      return e;
    }
    const char* changed = PQcmdTuples(result_);
    c_->set_changes(changed && *changed ? std::atoi(changed) : 0);
    rows_ = PQntuples(result_);
    row_ = -1;
  }
  return ++row_ < rows_;
}

void PgStatement::Reset() {
  if (result_) PQclear(result_);
  result_ = nullptr;
  row_ = -1;
  rows_ = 0;
  for (auto& v : values_) v.reset();
  std::fill(formats_.begin(), formats_.end(), 0);
}

int64_t PgStatement::Int(int col) const {
  if (IsNull(col)) return 0;
  return std::strtoll(PQgetvalue(result_, row_, col), nullptr, 10);
}
double PgStatement::Double(int col) const {
  if (IsNull(col)) return 0;
  return std::strtod(PQgetvalue(result_, row_, col), nullptr);
}
bool PgStatement::IsNull(int col) const {
  return !result_ || row_ < 0 || row_ >= rows_ || col >= PQnfields(result_) ||
         PQgetisnull(result_, row_, col);
}
std::string_view PgStatement::Text(int col) const {
  if (IsNull(col)) return {};
  return {PQgetvalue(result_, row_, col), static_cast<size_t>(PQgetlength(result_, row_, col))};
}

namespace {

// The server's side of "nothing acknowledged is lost" across a power cut: its WAL is flushed to
// the disk (fsync) and a page half-written by a cut is rebuilt from the WAL (full_page_writes).
// Either off is a server that can lose or corrupt committed rows, and the store refuses to write
// to it (synchronous_commit is the store's own session setting, above).
Status CheckServerDurability(pg_conn* conn) {
  pg_result* r =
      PQexec(conn, "SELECT current_setting('fsync'), current_setting('full_page_writes')");
  if (PQresultStatus(r) != PGRES_TUPLES_OK || PQntuples(r) != 1) {
    Error e = PgError(conn, r, "read the server's durability settings");
    PQclear(r);
    return e;
  }
  const std::string fsync = PQgetvalue(r, 0, 0), pages = PQgetvalue(r, 0, 1);
  PQclear(r);
  if (fsync != "on" || pages != "on")
    return Error{ErrorCode::kFailedPrecondition,
                 "PostgreSQL runs with fsync = " + fsync + " and full_page_writes = " + pages +
                     ": a power cut could lose or corrupt acknowledged records; the store needs "
                     "both on",
                 "db"};
  return Status::Ok();
}

}  // namespace

Expected<std::unique_ptr<Connection>> PgConnection::Open(const std::string& uri, Mode mode,
                                                         int busy_timeout_ms) {
  const char* keys[] = {"dbname", "connect_timeout", "application_name", nullptr};
  const char* values[] = {uri.c_str(), "5", "vsurg", nullptr};
  pg_conn* conn = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
  if (!conn) return Error{ErrorCode::kIoError, "PostgreSQL: out of memory", "db"};
  std::unique_ptr<PgConnection> c(new PgConnection(conn));
  if (PQstatus(conn) != CONNECTION_OK)
    return Error{ErrorCode::kUnavailable,
                 "PostgreSQL: " + PgError(conn, nullptr, "connect").message, "db"};
  PQsetNoticeProcessor(conn, IgnoreNotice, nullptr);
  // Durability as SQLite's synchronous=FULL: COMMIT returns after the WAL is flushed (the
  // server's default; said here so that a site's postgresql.conf cannot weaken it for us).
  c->setup_ = "SET synchronous_commit = on; SET lock_timeout = " + std::to_string(busy_timeout_ms) +
              "; SET client_encoding = 'UTF8'";
  if (mode == Mode::kReadOnly) c->setup_ += "; SET default_transaction_read_only = on";
  if (Status s = c->Apply(c->setup_.c_str()); !s.ok()) return s.error();
  if (mode == Mode::kReadWrite)
    if (Status s = CheckServerDurability(conn); !s.ok()) return s.error();
  return std::unique_ptr<Connection>(std::move(c));
}

bool PgConnection::Idle() const {
  return PQtransactionStatus(conn_) == PQTRANS_IDLE;
}

bool PgConnection::Reconnect() {
  PQreset(conn_);
  if (PQstatus(conn_) != CONNECTION_OK) return false;
  ++generation_;
  return Apply(setup_.c_str()).ok();
}

PgConnection::~PgConnection() {
  cache_.clear();
  PQfinish(conn_);
}

Expected<std::string> PgConnection::Renumber(const std::string& sql, int& params) {
  std::string out;
  out.reserve(sql.size());
  params = 0;
  bool quoted = false;
  for (size_t i = 0; i < sql.size(); ++i) {
    const char ch = sql[i];
    if (ch == '\'') quoted = !quoted;
    if (quoted || ch != '?') {
      out += ch;
      continue;
    }
    size_t j = i + 1;
    int n = 0;
    while (j < sql.size() && sql[j] >= '0' && sql[j] <= '9') n = n * 10 + (sql[j++] - '0');
    if (j == i + 1 || n < 1)
      return InvalidArgument("sql", "a parameter without a number in: " + sql);
    params = std::max(params, n);
    out += '$';
    out.append(sql, i + 1, j - i - 1);
    i = j - 1;
  }
  return out;
}

Expected<Statement*> PgConnection::Cached(const std::string& sql) {
  if (auto it = cache_.find(sql); it != cache_.end()) return it->second.get();
  int params = 0;
  auto text = Renumber(sql, params);
  if (!text.ok()) return text.error();
  std::string name = "vsurg_" + std::to_string(++next_name_);
  CountRoundTrip();
  pg_result* r = PQprepare(conn_, name.c_str(), text->c_str(), params, nullptr);
  if (!Succeeded(r)) {
    Error e = PgError(conn_, r, "prepare");
    PQclear(r);
    return e;
  }
  PQclear(r);
  auto [it, added] =
      cache_.emplace(sql, std::make_unique<PgStatement>(
                              this, std::move(name), std::move(text).value(), params, generation_));
  return it->second.get();
}

Status PgConnection::Exec(const char* sql) {
  // Between transactions (a BEGIN), a connection found lost is renewed and the command runs
  // again. Never inside one: a COMMIT on a new connection would "succeed" with nothing in it.
  // A connection already known lost is not renewed here either (Broken: the store replaces it).
  const bool idle = Idle();
  Status s = Apply(sql);
  if (!s.ok() && idle && PQstatus(conn_) == CONNECTION_BAD && Reconnect()) s = Apply(sql);
  return s;
}

Status PgConnection::Apply(const char* sql) {
  CountRoundTrip();
  pg_result* r = PQexec(conn_, sql);
  if (!Succeeded(r)) {
    Error e = PgError(conn_, r, sql);
    PQclear(r);
    return e;
  }
  PQclear(r);
  return Status::Ok();
}

Expected<int64_t> PgConnection::LastInsertId() {
  CountRoundTrip();
  pg_result* r = PQexec(conn_, "SELECT lastval()");
  if (!Succeeded(r) || PQntuples(r) != 1) {
    Error e = PgError(conn_, r, "lastval");
    PQclear(r);
    return e;
  }
  const int64_t id = std::strtoll(PQgetvalue(r, 0, 0), nullptr, 10);
  PQclear(r);
  return id;
}

Status PgConnection::LockSchema() {
  return Exec(kSchemaLock);
}

Status PgConnection::LockPlacements() {
  return Exec(kPlacementLock);
}

Expected<int> PgConnection::SchemaVersion() {
  auto exists = Prepare("SELECT to_regclass('vsurg_schema') IS NOT NULL");
  if (!exists.ok()) return exists.error();
  auto row = (*exists)->Step();
  if (!row.ok()) return row.error();
  const bool present = *row && (*exists)->Text(0) == "t";
  (*exists)->Reset();
  if (!present) return 0;
  auto st = Prepare("SELECT coalesce(max(version), 0) FROM vsurg_schema");
  if (!st.ok()) return st.error();
  row = (*st)->Step();
  if (!row.ok()) return row.error();
  const int64_t v = (*st)->Int(0);
  (*st)->Reset();
  return static_cast<int>(v);
}

Status PgConnection::SetSchemaVersion(int version) {
  if (Status s = Exec("CREATE TABLE IF NOT EXISTS vsurg_schema (version integer NOT NULL)");
      !s.ok())
    return s;
  if (Status s = Exec("DELETE FROM vsurg_schema"); !s.ok()) return s;
  auto st = Prepare("INSERT INTO vsurg_schema(version) VALUES (?1)");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, int64_t{version});
  return (*st)->Run();
}

bool PgConnection::Broken() const {
  return PQstatus(conn_) == CONNECTION_BAD;
}

Status PgConnection::Backup(const std::string& destination) {
  return Error{ErrorCode::kFailedPrecondition,
               "a PostgreSQL store is backed up with pg_dump or pg_basebackup, not to " +
                   destination + " (docs/SCALING.md)",
               "db"};
}

Expected<std::string> PgConnection::IntegrityCheck() {
  auto version = SchemaVersion();
  if (!version.ok()) return version.error();
  std::string out;
  auto st = Prepare("SELECT to_regclass(?1) IS NOT NULL");
  if (!st.ok()) return st.error();
  for (const char* table : kTables) {
    (*st)->Bind(1, table);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    const bool present = *row && (*st)->Text(0) == "t";
    (*st)->Reset();
    if (!present) out += std::string(out.empty() ? "" : "; ") + "table " + table + " is missing";
  }
  if (out.empty()) return std::string("ok");
  return out;
}

Status RunPostgresStatement(const std::string& uri, const std::string& sql) {
  auto c = PgConnection::Open(uri, Connection::Mode::kReadWrite, 5000);
  if (!c.ok()) return c.error();
  return (*c)->Exec(sql.c_str());
}

std::string PgConnection::PostgresDialect(const char* ddl) {
  struct Rule {
    std::regex from;
    const char* to;
  };
  static const Rule kRules[] = {
      {std::regex(R"(\bid(\s+)INTEGER PRIMARY KEY\b)"),
       "id$1BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY"},
      {std::regex(R"(\bINTEGER\b)"), "BIGINT"},
      {std::regex(R"(\bREAL\b)"), "DOUBLE PRECISION"},
      {std::regex(R"(\bBLOB\b)"), "BYTEA"},
      {std::regex(R"(\)\s*WITHOUT ROWID)"), ")"},
      {std::regex(R"(\bjson_valid\((\w+)\))"), "($1::jsonb IS NOT NULL)"},
      {std::regex(R"(\bifnull\()"), "coalesce("},
  };
  std::string out = ddl;
  for (const auto& rule : kRules) out = std::regex_replace(out, rule.from, rule.to);
  return out;
}

}  // namespace vsurg::db
