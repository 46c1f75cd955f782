// The store's database seam: a connection and its prepared statements, the same for every
// backend (DESIGN.md "Beyond one machine": one interface, two backends). db/sqlite.h is the
// embedded default, db/postgres.h the shared store of a multi-node site. The store's SQL is
// written once, with numbered parameters `?1`, `?2`, … (the PostgreSQL connection renumbers
// them `$1`, `$2`, …); nothing is ever built from input.
//
// Not thread-safe: a Connection and its statements belong to one thread at a time.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "common/core/expected.h"

namespace vsurg::db {

enum class Backend { kSqlite, kPostgres };

// A store location names its backend: a `postgresql://` or `postgres://` URI (libpq's
// connection URI) is PostgreSQL; anything else is an SQLite file path.
Backend BackendOf(std::string_view location);
const char* BackendName(Backend b);

class Statement {
 public:
  virtual ~Statement() = default;

  // Binds are 1-based, as in the SQL's `?N`.
  virtual Statement& Bind(int i, int64_t v) = 0;
  virtual Statement& Bind(int i, double v) = 0;
  virtual Statement& Bind(int i, std::string_view v) = 0;
  Statement& Bind(int i, const char* v) { return Bind(i, std::string_view(v)); }
  virtual Statement& BindBlob(int i, const void* data, int size) = 0;
  virtual Statement& BindNull(int i) = 0;
  Statement& Bind(int i, std::optional<double> v) { return v ? Bind(i, *v) : BindNull(i); }
  // An optional of any bindable type: its value, or NULL.
  template <typename T>
  Statement& BindOrNull(int i, const std::optional<T>& v) {
    return v ? Bind(i, *v) : BindNull(i);
  }

  // Step: true while a row is available, false when done; an error as Error.
  virtual Expected<bool> Step() = 0;
  // Steps to completion (for INSERT/UPDATE/DELETE) and resets.
  Status Run();
  virtual void Reset() = 0;  // clears bindings too

  virtual int64_t Int(int col) const = 0;
  virtual double Double(int col) const = 0;
  virtual bool IsNull(int col) const = 0;
  virtual std::string_view Text(int col) const = 0;
  std::string String(int col) const { return std::string(Text(col)); }
};

// A cached statement lent for one use. Its destructor resets it (rows released, bindings cleared,
// SQLite's read snapshot let go), so every path out of a caller, the early `return row.error()`
// and the not-found return among them, leaves the statement ready for the next user of the same
// SQL. A statement left mid-result would otherwise answer the next caller with the previous
// caller's bindings or rows.
class ScopedStatement {
 public:
  explicit ScopedStatement(Statement* s) : s_(s) {}
  ScopedStatement(ScopedStatement&& o) noexcept : s_(std::exchange(o.s_, nullptr)) {}
  ScopedStatement& operator=(ScopedStatement&&) = delete;
  ScopedStatement(const ScopedStatement&) = delete;
  ~ScopedStatement() {
    if (s_) s_->Reset();
  }
  Statement* operator->() const { return s_; }
  Statement& operator*() const { return *s_; }

 private:
  Statement* s_;
};

class Connection {
 public:
  enum class Mode { kReadWrite, kReadOnly };
  // Opens the location's backend. SQLite: creates the file for kReadWrite; WAL,
  // synchronous=FULL, foreign keys, a busy timeout. PostgreSQL: connects; kReadOnly makes every
  // transaction read-only; the busy timeout becomes the lock timeout.
  static Expected<std::unique_ptr<Connection>> Open(const std::string& location, Mode mode,
                                                    int busy_timeout_ms = 5000);
  virtual ~Connection() = default;

  virtual Backend backend() const = 0;
  // Prepared once per SQL text and cached for the connection's life, lent for the caller's scope
  // and reset when the handle is dropped. Two live handles of the same SQL share one statement.
  Expected<ScopedStatement> Prepare(const std::string& sql) {
    auto st = Cached(sql);
    if (!st.ok()) return st.error();
    return ScopedStatement(*st);
  }
  // For DDL and statements without values only (migrations, transaction control).
  virtual Status Exec(const char* sql) = 0;
  // The id the last INSERT on this connection gave its row.
  virtual Expected<int64_t> LastInsertId() = 0;
  // Rows changed by the last INSERT/UPDATE/DELETE.
  virtual int Changes() const = 0;
  // A write transaction that holds the write lock from its start (SQLite: BEGIN IMMEDIATE).
  virtual Status BeginWrite() = 0;
  // A read transaction that sees one snapshot throughout (for exports).
  virtual Status BeginSnapshot() = 0;
  // Inside a write transaction: serialises schema changes between processes that migrate the
  // same database at once (PostgreSQL: a transaction-scoped advisory lock; SQLite's
  // BEGIN IMMEDIATE already does).
  virtual Status LockSchema() = 0;
  // The same for placement (Store::ReservePlacement): one control replica at a time reads the
  // nodes' load and reserves its choice; on PostgreSQL that transaction's commit does not wait
  // for the WAL's flush (a reservation is a transient count, never acknowledged to anyone).
  virtual Status LockPlacements() = 0;
  virtual Expected<int> SchemaVersion() = 0;
  virtual Status SetSchemaVersion(int version) = 0;
  // The schema text of a migration, in this backend's dialect (db/migrations.cpp).
  virtual std::string Dialect(const char* ddl) const = 0;
  // True when the connection is lost for good (the server went away); the store then opens a
  // new one instead of reusing it.
  virtual bool Broken() const = 0;
  // Requests this connection has sent its server and waited for (PostgreSQL); SQLite is in the
  // process and has none (0).
  virtual uint64_t RoundTrips() const = 0;
  // Backend-specific maintenance.
  virtual Status Backup(const std::string& destination) = 0;
  virtual Expected<std::string> IntegrityCheck() = 0;

 protected:
  // The backend's statement cache: prepares `sql` on first use; the pointer stays valid for the
  // connection's life.
  virtual Expected<Statement*> Cached(const std::string& sql) = 0;
};

}  // namespace vsurg::db
