#include "db/sqlite.h"

#include <sqlite3.h>

namespace vsurg::db {

Error SqliteError(sqlite3* db, int rc, std::string_view what) {
  const int primary = rc & 0xff;
  std::string message = std::string(what) + ": " + (db ? sqlite3_errmsg(db) : sqlite3_errstr(rc));
  ErrorCode code = ErrorCode::kIoError;
  if (rc == SQLITE_CONSTRAINT_UNIQUE || rc == SQLITE_CONSTRAINT_PRIMARYKEY) {
    code = ErrorCode::kAlreadyExists;
  } else if (primary == SQLITE_CONSTRAINT) {
    code = ErrorCode::kInvalidArgument;
  } else if (primary == SQLITE_BUSY || primary == SQLITE_LOCKED) {
    code = ErrorCode::kUnavailable;
  }
  return Error{code, std::move(message), ""};
}

SqliteStatement::~SqliteStatement() {
  if (stmt_) sqlite3_finalize(stmt_);
}

Statement& SqliteStatement::Bind(int i, int64_t v) {
  sqlite3_bind_int64(stmt_, i, v);
  return *this;
}
Statement& SqliteStatement::Bind(int i, double v) {
  sqlite3_bind_double(stmt_, i, v);
  return *this;
}
Statement& SqliteStatement::Bind(int i, std::string_view v) {
  sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  return *this;
}
Statement& SqliteStatement::BindBlob(int i, const void* data, int size) {
  sqlite3_bind_blob(stmt_, i, data, size, SQLITE_TRANSIENT);
  return *this;
}
Statement& SqliteStatement::BindNull(int i) {
  sqlite3_bind_null(stmt_, i);
  return *this;
}

Expected<bool> SqliteStatement::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  Error e = SqliteError(db_, rc, "step");
  sqlite3_reset(stmt_);
  return e;
}

void SqliteStatement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int64_t SqliteStatement::Int(int col) const {
  return sqlite3_column_int64(stmt_, col);
}
double SqliteStatement::Double(int col) const {
  return sqlite3_column_double(stmt_, col);
}
bool SqliteStatement::IsNull(int col) const {
  return sqlite3_column_type(stmt_, col) == SQLITE_NULL;
}
std::string_view SqliteStatement::Text(int col) const {
  const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
  return p ? std::string_view(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, col)))
           : std::string_view();
}

Expected<std::unique_ptr<Connection>> SqliteConnection::Open(const std::string& path, Mode mode,
                                                             int busy_timeout_ms) {
  sqlite3* db = nullptr;
  const int flags = (mode == Mode::kReadWrite ? SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE
                                              : SQLITE_OPEN_READONLY) |
                    SQLITE_OPEN_NOMUTEX;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  if (rc != SQLITE_OK) {
    Error e = SqliteError(db, rc, "open " + path);
    sqlite3_close(db);
    return e;
  }
  std::unique_ptr<SqliteConnection> c(new SqliteConnection(db));
  sqlite3_busy_timeout(db, busy_timeout_ms);
  sqlite3_extended_result_codes(db, 1);
  // WAL: readers never block the writer; FULL: a commit is on disk (WAL fsync) before it
  // returns, so nothing acknowledged is lost on a crash or power cut.
  for (const char* pragma : {"PRAGMA foreign_keys=ON", "PRAGMA synchronous=FULL"})
    if (Status s = c->Exec(pragma); !s.ok()) return s.error();
  if (mode == Mode::kReadWrite) {
    if (Status s = c->Exec("PRAGMA journal_mode=WAL"); !s.ok()) return s.error();
  } else {
    // Readers map the file instead of copying each page through read(): the training grid
    // reads a course's 100,000 trials per request (docs/BENCHMARKS.md "The training programme
    // at scale"). Address space only; the pages are the kernel's page cache either way.
    if (Status s = c->Exec("PRAGMA mmap_size=268435456"); !s.ok()) return s.error();
  }
  return std::unique_ptr<Connection>(std::move(c));
}

SqliteConnection::~SqliteConnection() {
  cache_.clear();  // statements finalised before the close
  sqlite3_close(db_);
}

Expected<Statement*> SqliteConnection::Cached(const std::string& sql) {
  if (auto it = cache_.find(sql); it != cache_.end()) return it->second.get();
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db_, sql.c_str(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (rc != SQLITE_OK) return SqliteError(db_, rc, "prepare");
  auto [it, added] = cache_.emplace(sql, std::make_unique<SqliteStatement>(db_, stmt));
  return it->second.get();
}

Status SqliteConnection::Exec(const char* sql) {
  char* message = nullptr;
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &message);
  if (rc != SQLITE_OK) {
    Error e = SqliteError(db_, rc, sql);
    sqlite3_free(message);
    return e;
  }
  return Status::Ok();
}

Expected<int64_t> SqliteConnection::LastInsertId() {
  return static_cast<int64_t>(sqlite3_last_insert_rowid(db_));
}
int SqliteConnection::Changes() const {
  return sqlite3_changes(db_);
}

Expected<int> SqliteConnection::SchemaVersion() {
  auto st = Prepare("PRAGMA user_version");
  if (!st.ok()) return st.error();
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  const int64_t v = *row ? (*st)->Int(0) : 0;
  (*st)->Reset();
  return static_cast<int>(v);
}

Status SqliteConnection::SetSchemaVersion(int version) {
  // PRAGMA takes no bound values; the number is ours, not input.
  const std::string bump = "PRAGMA user_version=" + std::to_string(version);
  return Exec(bump.c_str());
}

Status SqliteConnection::Backup(const std::string& destination) {
  sqlite3* dest = nullptr;
  int rc = sqlite3_open_v2(destination.c_str(), &dest, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE,
                           nullptr);
  if (rc != SQLITE_OK) {
    Error e = SqliteError(dest, rc, "backup to " + destination);
    sqlite3_close(dest);
    return e;
  }
  sqlite3_backup* b = sqlite3_backup_init(dest, "main", db_, "main");
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

Expected<std::string> SqliteConnection::IntegrityCheck() {
  auto st = Prepare("PRAGMA integrity_check");
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
