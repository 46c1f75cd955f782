// A palpation's sessions (server/session/session_manager.h): each session draws its own case,
// taken from the bank kept ahead, and the case moves with the session. A real store and a real
// UDP endpoint on loopback.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "common/sim/palpation_case.h"
#include "server/session/session_manager.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::server {
namespace {

namespace fs = std::filesystem;

class PalpationSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The reduced models' cache of this test alone (the bank and the sessions share it).
    setenv("VSURG_CACHE_DIR", cache_.string().c_str(), 1);
    store_ = db::Store::Open({.path = (dir_.path() / "vsurg.db").string()}).value();
    endpoint_ = UdpEndpoint::Create({}).value();
  }
  void TearDown() override {
    sessions_.reset();
    endpoint_.reset();
    store_.reset();
    unsetenv("VSURG_CACHE_DIR");
  }
  void Open(int cases_ready) {
    SessionManagerOptions so;
    so.cases_ready = cases_ready;
    sessions_ = SessionManager::Open(*store_, endpoint_.get(), so).value();
  }
  // The case a live session practises, as its handoff carries it (the move is then cancelled).
  std::optional<uint64_t> CaseOf(const CreatedSession& s) {
    auto h = sessions_->BeginMove(static_cast<uint64_t>(s.record.id));
    EXPECT_TRUE(h.ok()) << h.error().message;
    sessions_->CancelMove(static_cast<uint64_t>(s.record.id));
    return h.ok() ? h->case_seed : std::nullopt;
  }

  test::TempDir dir_{"palpation_session"};
  test::TempDir cache_{"palpation_session_cache"};
  std::unique_ptr<db::Store> store_;
  std::unique_ptr<UdpEndpoint> endpoint_;
  std::unique_ptr<SessionManager> sessions_;
};

TEST_F(PalpationSessionTest, EachSessionTakesAReadyCaseOfItsOwnAndItsFileIsRemoved) {
  Open(1);
  test::Eventually(300, [&] { return sessions_->cases().stats().ready >= 1; });
  ASSERT_GE(sessions_->cases().stats().ready, 1u) << "the bank built no case in 300 s";
  auto a = sessions_->Create("trainee-a", "lump-search");
  ASSERT_TRUE(a.ok()) << a.error().message;
  EXPECT_EQ(sessions_->cases().stats().taken, 1u);
  EXPECT_EQ(sessions_->cases().stats().missed, 0u);
  const std::optional<uint64_t> case_a = CaseOf(*a);
  ASSERT_TRUE(case_a.has_value());
  EXPECT_FALSE(fs::exists(cache_.path() / (sim::CaseName("lump-search", *case_a) + "-contact.vrm")))
      << "a taken case's table file is removed once its session has loaded it";
  auto b = sessions_->Create("trainee-b", "lump-search");
  ASSERT_TRUE(b.ok()) << b.error().message;
  const std::optional<uint64_t> case_b = CaseOf(*b);
  ASSERT_TRUE(case_b.has_value());
  EXPECT_NE(*case_a, *case_b) << "two attempts practise two cases";
  // A scene without cases has none.
  auto twist = sessions_->Create("trainee-a", "arm-torsion");
  ASSERT_TRUE(twist.ok()) << twist.error().message;
  EXPECT_FALSE(CaseOf(*twist).has_value());
}

// The case travels with a moved session: the handoff's bytes carry it (the adopting node redraws
// the same lumps from it: DrawCase is the same for the same seed, palpation_test), and a session
// built without a bank draws a case of its own.
TEST_F(PalpationSessionTest, AMovedSessionsHandoffCarriesItsCase) {
  Open(0);  // no bank: the session builds its own case
  auto a = sessions_->Create("trainee-a", "lump-search");
  ASSERT_TRUE(a.ok()) << a.error().message;
  EXPECT_EQ(sessions_->cases().stats().missed, 1u);
  const uint64_t id = static_cast<uint64_t>(a->record.id);
  auto h = sessions_->BeginMove(id);
  ASSERT_TRUE(h.ok()) << h.error().message;
  ASSERT_TRUE(h->case_seed.has_value());
  h->from_node = "node-a";  // as a node's handoff says (this server is all-in-one)
  auto back = SessionHandoff::FromBytes(h->Bytes());
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->case_seed, h->case_seed);
  sessions_->CancelMove(id);
  // Without a case the handoff says so.
  h->case_seed.reset();
  auto none = SessionHandoff::FromBytes(h->Bytes());
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->case_seed.has_value());
}

}  // namespace
}  // namespace vsurg::server
