// Forward-only schema migrations, numbered by PRAGMA user_version. Migration i (1-based) takes a
// database from version i−1 to i and is never edited once released: a change is a new entry.
#pragma once

#include <vector>

#include "common/core/expected.h"

namespace vsurg::db {

class Connection;

const std::vector<const char*>& Migrations();
// Applies the missing migrations, each in its own transaction with its user_version bump.
// A file newer than Migrations().size() is refused.
Status Migrate(Connection& c);

}  // namespace vsurg::db
