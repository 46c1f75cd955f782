// A real PostgreSQL for the tests (deploy/postgres.sh): the ctest fixture `postgres` starts one
// server for the whole run and names its URI in the file $VSURG_TEST_POSTGRES_FILE (or a caller
// names one in $VSURG_TEST_POSTGRES_URI, which wins); a test binary run by hand starts its own on
// first use and stops it at exit. Each test takes a database of its
// own (FreshDatabase), so tests never see each other's rows.
#pragma once

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "db/postgres.h"

#ifndef VSURG_SOURCE_DIR
#error "tests that use PostgreSQL are compiled with VSURG_SOURCE_DIR (the repository root)"
#endif

namespace vsurg::test {

// The URI of the server's `vsurg` database (the maintenance database for CREATE DATABASE).
inline const std::string& PostgresUri() {
  static std::once_flag once;
  static std::string uri;
  std::call_once(once, [] {
    // A server named by its URI comes first: a ctest run beside another in the same build folder
    // (deploy/sanitize.sh) has one of its own, while the fixture's file names the other's.
    if (const char* given = std::getenv("VSURG_TEST_POSTGRES_URI"); given && *given) {
      uri = given;
      return;
    }
    if (const char* file = std::getenv("VSURG_TEST_POSTGRES_FILE")) {
      std::ifstream in(file);
      std::getline(in, uri);
      if (!uri.empty()) return;
    }
    // Our own server, stopped (and its folder removed) when the process exits.
    static const std::string dir =
        (std::filesystem::temp_directory_path() / ("vsurg_pg_" + std::to_string(::getpid())))
            .string();
    const std::string script = std::string(VSURG_SOURCE_DIR) + "/deploy/postgres.sh";
    if (std::system((script + " start " + dir + " >/dev/null").c_str()) != 0)
      throw std::runtime_error("deploy/postgres.sh could not start PostgreSQL in " + dir);
    std::ifstream in(dir + "/uri");
    std::getline(in, uri);
    std::atexit([] {
      const std::string stop = std::string(VSURG_SOURCE_DIR) + "/deploy/postgres.sh stop " + dir;
      (void)std::system(stop.c_str());
    });
  });
  return uri;
}

// Runs one statement on the maintenance database; throws on failure.
inline void PostgresAdmin(const std::string& sql) {
  if (Status s = db::RunPostgresStatement(PostgresUri(), sql); !s.ok())
    throw std::runtime_error(sql + ": " + s.error().message);
}

// A new empty database on the test server, dropped with this object (closing any connection
// still on it).
class PostgresDatabase {
 public:
  PostgresDatabase() {
    static std::atomic<int> counter{0};
    name_ = "t" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
    PostgresAdmin("CREATE DATABASE " + name_);
    const std::string& base = PostgresUri();
    uri_ = base.substr(0, base.rfind('/') + 1) + name_;
  }
  ~PostgresDatabase() {
    try {
      PostgresAdmin("DROP DATABASE IF EXISTS " + name_ + " WITH (FORCE)");
    } catch (...) {
    }
  }
  PostgresDatabase(const PostgresDatabase&) = delete;
  PostgresDatabase& operator=(const PostgresDatabase&) = delete;
  const std::string& uri() const { return uri_; }

 private:
  std::string name_, uri_;
};

}  // namespace vsurg::test
