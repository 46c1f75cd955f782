// The embedded backend: a thin RAII layer over the SQLite C API (one file, WAL,
// synchronous=FULL, foreign keys on, schema version in PRAGMA user_version).
#pragma once

#include <map>
#include <memory>
#include <string>

#include "db/connection.h"

struct sqlite3;
struct sqlite3_stmt;

namespace vsurg::db {

class SqliteStatement final : public Statement {
 public:
  SqliteStatement(sqlite3* db, sqlite3_stmt* stmt) : db_(db), stmt_(stmt) {}
  ~SqliteStatement() override;
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;

  using Statement::Bind;
  Statement& Bind(int i, int64_t v) override;
  Statement& Bind(int i, double v) override;
  Statement& Bind(int i, std::string_view v) override;
  Statement& BindBlob(int i, const void* data, int size) override;
  Statement& BindNull(int i) override;
  Expected<bool> Step() override;
  void Reset() override;
  int64_t Int(int col) const override;
  double Double(int col) const override;
  bool IsNull(int col) const override;
  std::string_view Text(int col) const override;

 private:
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
};

// Maps an SQLite result code and message to an Error (constraint failures become
// kAlreadyExists or kInvalidArgument, busy/locked kUnavailable, the rest kIoError).
Error SqliteError(sqlite3* db, int rc, std::string_view what);

class SqliteConnection final : public Connection {
 public:
  static Expected<std::unique_ptr<Connection>> Open(const std::string& path, Mode mode,
                                                    int busy_timeout_ms);
  ~SqliteConnection() override;
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;

  Backend backend() const override { return Backend::kSqlite; }
  Status Exec(const char* sql) override;
  Expected<int64_t> LastInsertId() override;
  int Changes() const override;
  Status BeginWrite() override { return Exec("BEGIN IMMEDIATE"); }
  Status BeginSnapshot() override { return Exec("BEGIN"); }
  Status LockSchema() override { return Status::Ok(); }
  Status LockPlacements() override { return Status::Ok(); }
  Expected<int> SchemaVersion() override;
  Status SetSchemaVersion(int version) override;
  std::string Dialect(const char* ddl) const override { return ddl; }
  bool Broken() const override { return false; }
  uint64_t RoundTrips() const override { return 0; }
  // Online backup to a new file, 256 pages at a time (writers are not held off meanwhile).
  Status Backup(const std::string& destination) override;
  Expected<std::string> IntegrityCheck() override;  // PRAGMA integrity_check

 protected:
  Expected<Statement*> Cached(const std::string& sql) override;

 private:
  explicit SqliteConnection(sqlite3* db) : db_(db) {}
  sqlite3* db_ = nullptr;
  std::map<std::string, std::unique_ptr<SqliteStatement>, std::less<>> cache_;
};

}  // namespace vsurg::db
