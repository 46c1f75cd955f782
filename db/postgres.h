// The shared backend: a thin RAII layer over libpq (PostgreSQL 15, Debian's libpq-dev), for a
// site where several control replicas write one store. libpq rather than libpqxx: the store
// already has its own statement layer (db/connection.h), and libpq's C API maps onto it
// one to one with nothing in between.
//
// Values go as text parameters of server-side prepared statements (blobs as binary), results
// come back as text; the schema's types are mapped in Dialect (64-bit integers, double
// precision, bytea, identity columns), so a row reads back the same as from SQLite.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "db/connection.h"

struct pg_conn;
struct pg_result;

namespace vsurg::db {

class PgConnection;

class PgStatement final : public Statement {
 public:
  PgStatement(PgConnection* c, std::string name, std::string text, int params, int generation);
  ~PgStatement() override;
  PgStatement(const PgStatement&) = delete;
  PgStatement& operator=(const PgStatement&) = delete;

  using Statement::Bind;
  Statement& Bind(int i, int64_t v) override;
  Statement& Bind(int i, double v) override;
  Statement& Bind(int i, std::string_view v) override;
  Statement& BindBlob(int i, const void* data, int size) override;
  Statement& BindNull(int i) override;
  // The first Step runs the statement and keeps its rows; later Steps walk them.
  Expected<bool> Step() override;
  void Reset() override;
  int64_t Int(int col) const override;
  double Double(int col) const override;
  bool IsNull(int col) const override;
  std::string_view Text(int col) const override;

 private:
  void Set(int i, std::string value, int format);
  pg_result* Execute();
  PgConnection* c_;
  std::string name_, text_;  // the server-side name, and the SQL with $N
  int generation_;           // the connection generation it was prepared on
  std::vector<std::optional<std::string>> values_;
  std::vector<int> formats_;  // 0 text, 1 binary
  pg_result* result_ = nullptr;
  int row_ = -1, rows_ = 0;
};

class PgConnection final : public Connection {
 public:
  static Expected<std::unique_ptr<Connection>> Open(const std::string& uri, Mode mode,
                                                    int busy_timeout_ms);
  ~PgConnection() override;
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  Backend backend() const override { return Backend::kPostgres; }
  Status Exec(const char* sql) override;
  Expected<int64_t> LastInsertId() override;  // lastval(): the sequence this session used last
  int Changes() const override { return changes_; }
  Status BeginWrite() override { return Exec("BEGIN"); }
  Status BeginSnapshot() override {
    return Exec("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY");
  }
  Status LockSchema() override;
  Status LockPlacements() override;
  Expected<int> SchemaVersion() override;
  Status SetSchemaVersion(int version) override;
  std::string Dialect(const char* ddl) const override { return PostgresDialect(ddl); }
  bool Broken() const override;
  uint64_t RoundTrips() const override { return round_trips_; }
  void CountRoundTrip() { ++round_trips_; }
  // PostgreSQL is backed up by its own tools (pg_dump, pg_basebackup): kFailedPrecondition.
  Status Backup(const std::string& destination) override;
  // The server answers, the schema is this binary's, and every table of it is there.
  Expected<std::string> IntegrityCheck() override;

  // The SQLite schema text rewritten for PostgreSQL: INTEGER → BIGINT (and `id INTEGER PRIMARY
  // KEY` → an identity column), REAL → DOUBLE PRECISION, BLOB → BYTEA, json_valid(x) → a jsonb
  // cast, ifnull → coalesce, no WITHOUT ROWID. Only our own migrations go through it.
  static std::string PostgresDialect(const char* ddl);
  // `?N` → `$N` outside quoted text; a bare `?` is a programming error (kInvalidArgument).
  static Expected<std::string> Renumber(const std::string& sql, int& params);

  pg_conn* handle() { return conn_; }
  void set_changes(int n) { changes_ = n; }
  // Reconnects after a lost connection (PQreset), with this connection's settings; the
  // statements prepare themselves again on their next run (a new generation). Only between
  // transactions: inside one, its work is gone with the connection and it fails instead.
  bool Reconnect();
  int generation() const { return generation_; }
  bool Idle() const;  // no transaction open (as far as libpq knows)

 protected:
  Expected<Statement*> Cached(const std::string& sql) override;

 private:
  explicit PgConnection(pg_conn* conn) : conn_(conn) {}
  Status Apply(const char* sql);  // Exec without the reconnect
  pg_conn* conn_ = nullptr;
  std::string setup_;  // the session settings, again after a reconnect
  int generation_ = 0;
  int changes_ = 0;
  int next_name_ = 0;
  uint64_t round_trips_ = 0;
  std::map<std::string, std::unique_ptr<PgStatement>, std::less<>> cache_;
};

// Runs one statement without values on the server at `uri` over a connection of its own (CREATE
// or DROP DATABASE for the tests' and benchmarks' databases: not for the store's data).
Status RunPostgresStatement(const std::string& uri, const std::string& sql);

// Maps a failed libpq result (its SQLSTATE) to an Error: unique violations kAlreadyExists,
// other integrity and data errors kInvalidArgument, lost connections, serialisation failures
// and shutdowns kUnavailable (retrying may succeed), the rest kIoError.
Error PgError(pg_conn* conn, pg_result* result, std::string_view what);

}  // namespace vsurg::db
