// The store suites' fixture: every store test runs on both backends.
#pragma once

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "db/connection.h"
#include "db/store.h"
#include "tests/support/postgres.h"
#include "tests/support/temp_dir.h"

namespace vsurg::db::test_store {

// A simulation node's record as its first heartbeat gives it: sim-0 of process-a, room for 24.
inline NodeRecord SimNode() {
  NodeRecord n;
  n.name = "sim-0";
  n.grpc_address = "10.0.0.1:7000";
  n.udp_host = "10.0.0.1";
  n.udp_port = 7001;
  n.capacity = 24;
  n.heartbeat_us = 1000;
  n.instance = "process-a";
  return n;
}

// Every store test runs on both backends: an SQLite file in a temporary folder, and a database
// of its own on a real PostgreSQL (tests/support/postgres.h).
class StoreTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    if (sqlite()) {
      path_ = (dir_ / "vsurg.db").string();
    } else {
      pg_ = std::make_unique<vsurg::test::PostgresDatabase>();
      path_ = pg_->uri();
    }
    auto s = Store::Open({.path = path_});
    ASSERT_TRUE(s.ok()) << s.error().message;
    store_ = std::move(s).value();
  }
  void TearDown() override {
    store_.reset();
    pg_.reset();
  }
  bool sqlite() const { return GetParam() == Backend::kSqlite; }
  // The schema version as the backend keeps it, read through a connection of its own.
  int Version() {
    auto c = Connection::Open(path_, Connection::Mode::kReadOnly);
    EXPECT_TRUE(c.ok()) << c.error().message;
    auto v = (*c)->SchemaVersion();
    EXPECT_TRUE(v.ok());
    return v.ok() ? *v : -1;
  }
  void SetVersion(int v) {
    auto c = Connection::Open(path_, Connection::Mode::kReadWrite);
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE((*c)->SetSchemaVersion(v).ok());
  }

  Submission Valid(const std::string& key, const std::string& evaluator = "dr-a",
                   const std::string& subject = "coil-spring") {
    Submission s;
    s.idempotency_key = key;
    s.evaluator = evaluator;
    s.evaluator_group = "chief";
    s.subject_kind = SubjectKind::kModel;
    s.subject = subject;
    s.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
    s.submitted_by = "root";
    return s;
  }

  int64_t Rows() { return store_->CountEvaluationRows().value(); }

  vsurg::test::TempDir dir_{"store"};
  std::string path_;
  std::unique_ptr<vsurg::test::PostgresDatabase> pg_;
  std::unique_ptr<Store> store_;
};

}  // namespace vsurg::db::test_store
