// Forward-only schema migrations, numbered by the schema version (SQLite's PRAGMA user_version,
// PostgreSQL's vsurg_schema table). Migration i (1-based) takes a database from version i−1 to i
// and is never edited once released: a change is a new entry. The text is SQLite's; each
// backend's Connection::Dialect maps its types (db/postgres.h).
#pragma once

#include <vector>

#include "common/core/expected.h"

namespace vsurg::db {

class Connection;

const std::vector<const char*>& Migrations();
// Applies the missing migrations, each in its own transaction with its version bump, under the
// backend's schema lock. A database newer than Migrations().size() is refused.
Status Migrate(Connection& c);

}  // namespace vsurg::db
