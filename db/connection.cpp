#include "db/connection.h"

#include "db/postgres.h"
#include "db/sqlite.h"

namespace vsurg::db {

Backend BackendOf(std::string_view location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://")
             ? Backend::kPostgres
             : Backend::kSqlite;
}

const char* BackendName(Backend b) {
  return b == Backend::kPostgres ? "postgresql" : "sqlite";
}

Status Statement::Run() {
  auto r = Step();
  Reset();
  if (!r.ok()) return r.error();
  return Status::Ok();
}

Expected<std::unique_ptr<Connection>> Connection::Open(const std::string& location, Mode mode,
                                                       int busy_timeout_ms) {
  if (BackendOf(location) == Backend::kPostgres)
    return PgConnection::Open(location, mode, busy_timeout_ms);
  return SqliteConnection::Open(location, mode, busy_timeout_ms);
}

}  // namespace vsurg::db
