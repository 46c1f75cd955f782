// A thin RAII layer over the SQLite C API: a connection with the store's pragmas, and prepared
// statements (the only way SQL with values is run here: no string-built queries).
//
// Not thread-safe: a Connection and its statements belong to one thread at a time.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "common/core/expected.h"

struct sqlite3;
struct sqlite3_stmt;

namespace vsurg::db {

class Statement {
 public:
  Statement() = default;
  Statement(sqlite3* db, sqlite3_stmt* stmt) : db_(db), stmt_(stmt) {}
  ~Statement();
  Statement(Statement&& o) noexcept : db_(o.db_), stmt_(o.stmt_) { o.stmt_ = nullptr; }
  Statement& operator=(Statement&& o) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Binds are 1-based, as in SQLite.
  Statement& Bind(int i, int64_t v);
  Statement& Bind(int i, double v);
  Statement& Bind(int i, std::string_view v);
  Statement& Bind(int i, const char* v) { return Bind(i, std::string_view(v)); }
  Statement& BindBlob(int i, const void* data, int size);
  Statement& BindNull(int i);
  Statement& Bind(int i, std::optional<double> v) { return v ? Bind(i, *v) : BindNull(i); }

  // Step: true while a row is available, false when done; an error as Error.
  Expected<bool> Step();
  // Steps to completion (for INSERT/UPDATE/DELETE) and resets.
  Status Run();
  void Reset();  // clears bindings too

  int64_t Int(int col) const;
  double Double(int col) const;
  bool IsNull(int col) const;
  std::string_view Text(int col) const;
  std::string String(int col) const { return std::string(Text(col)); }

 private:
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
};

// Maps an SQLite result code and message to an Error (constraint failures become
// kAlreadyExists or kInvalidArgument, busy/locked kUnavailable, the rest kIoError).
Error SqliteError(sqlite3* db, int rc, std::string_view what);

class Connection {
 public:
  enum class Mode { kReadWrite, kReadOnly };
  // Opens (creating for kReadWrite) with WAL, synchronous=FULL, foreign_keys=ON and a busy
  // timeout.
  static Expected<std::unique_ptr<Connection>> Open(const std::string& path, Mode mode,
                                                    int busy_timeout_ms = 5000);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // Prepared once per SQL text and cached for the connection's life; the reference stays valid.
  Expected<Statement*> Prepare(const std::string& sql);
  // For DDL and pragmas without values only (migrations, BEGIN/COMMIT).
  Status Exec(const char* sql);
  int64_t LastInsertId() const;
  int Changes() const;
  sqlite3* handle() { return db_; }

 private:
  explicit Connection(sqlite3* db) : db_(db) {}
  sqlite3* db_ = nullptr;
  std::map<std::string, Statement, std::less<>> cache_;
};

}  // namespace vsurg::db
