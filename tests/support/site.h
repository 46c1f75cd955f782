// One site in this process for a test: a store in a folder of its own, the sessions over it (with
// a UDP endpoint when the test runs stations), the first administrator's token, and the users a
// test names, each with a token. The fixtures of the domain, the HTTP API and server and the gRPC
// control plane derive from it; each adds its own transport.
#pragma once

#include <initializer_list>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "db/store.h"
#include "server/session/session_manager.h"
#include "tests/support/temp_dir.h"

namespace vsurg::test {

class SiteTest : public ::testing::Test {
 protected:
  struct User {
    std::string name;
    db::Role role;
    std::string group;
  };

  // From the derived fixture's SetUp, before anything that uses the store or the sessions.
  void OpenSite(server::UdpEndpoint* endpoint = nullptr,
                const server::SessionManagerOptions& options = {}) {
    auto store = db::Store::Open({.path = (dir_ / "vsurg.db").string()});
    ASSERT_TRUE(store.ok()) << store.error().message;
    store_ = std::move(store).value();
    auto sessions = server::SessionManager::Open(*store_, endpoint, options);
    ASSERT_TRUE(sessions.ok()) << sessions.error().message;
    sessions_ = std::move(sessions).value();
    auto admin = store_->InitAdmin("root");
    ASSERT_TRUE(admin.ok()) << admin.error().message;
    admin_ = *admin;
  }
  // Creates each user and issues them a token (tokens_[name]).
  void AddUsers(std::initializer_list<User> users) {
    for (const User& u : users) {
      ASSERT_TRUE(store_->CreateUser(u.name, u.role, u.group).ok()) << u.name;
      tokens_[u.name] = store_->IssueToken(u.name, "test").value();
    }
  }
  std::string backups() const { return (dir_ / "backups").string(); }
  // A user as the transports authenticate them (the domain's caller).
  db::Principal As(const std::string& name) {
    const std::vector<db::UserRecord> users = store_->ListUsers().value();
    for (const db::UserRecord& u : users)
      if (u.name == name) return {u.id, u.name, u.role, u.group};
    ADD_FAILURE() << "no user " << name;
    return {};
  }
  // A derived fixture's TearDown stops its transport first, then calls this.
  void TearDown() override {
    sessions_.reset();
    store_.reset();
  }

  TempDir dir_{"site"};  // first: it outlives the store in it
  std::unique_ptr<db::Store> store_;
  std::unique_ptr<server::SessionManager> sessions_;
  std::string admin_;                          // the first administrator's token
  std::map<std::string, std::string> tokens_;  // by user name
};

}  // namespace vsurg::test
