// The node registry in the store: leases and their epochs, fenced session writes, a node's fall
// and its sessions, live migration between leases; renewing a lease is one request to a shared
// store (the control plane renews every node's lease every few seconds).
#include <atomic>
#include <future>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "db/store.h"
#include "tests/db/store_fixture.h"
#include "tests/support/wait.h"

namespace vsurg::db {
namespace {

class StoreLeaseTest : public test_store::StoreTest {};

INSTANTIATE_TEST_SUITE_P(Backends, StoreLeaseTest,
                         ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& p) { return std::string(BackendName(p.param)); });

TEST_P(StoreLeaseTest, ALeaseRenewalIsOneRoundTrip) {
  NodeRecord n = test_store::SimNode();
  n.epoch = store_->AcquireNode(n, 2000, "restarted").value().epoch;
  ASSERT_TRUE(store_->BeatNode(n).ok());  // the statement is prepared on its first use
  const uint64_t before = store_->stats().writer_round_trips;
  constexpr int kBeats = 5;
  for (int i = 0; i < kBeats; ++i) {
    n.heartbeat_us += 500;
    n.sessions = i;
    ASSERT_TRUE(store_->BeatNode(n).ok());
  }
  const uint64_t trips = store_->stats().writer_round_trips - before;
  EXPECT_EQ(trips, sqlite() ? 0u : static_cast<uint64_t>(kBeats));  // SQLite has no server
  // Each renewal is durable on its own: a new store reads the last one.
  store_.reset();
  auto again = Store::Open({.path = path_});
  ASSERT_TRUE(again.ok());
  auto nodes = (*again)->ListNodes();
  ASSERT_TRUE(nodes.ok());
  ASSERT_EQ(nodes->size(), 1u);
  EXPECT_EQ((*nodes)[0].heartbeat_us, n.heartbeat_us);
  EXPECT_EQ((*nodes)[0].sessions, kBeats - 1);
}

// A renewal between other writes of a batch neither joins their transaction nor breaks it.
TEST_P(StoreLeaseTest, RenewalsBesideOtherWritesLeaveEveryWriteRight) {
  NodeRecord n = test_store::SimNode();
  n.epoch = store_->AcquireNode(n, 2000, "restarted").value().epoch;
  NodeRecord lost = n;
  lost.epoch += 1;
  std::vector<std::future<Status>> results;
  for (int i = 0; i < 20; ++i) {
    results.push_back(std::async(std::launch::async, [&, i] {
      if (i % 4 == 0) {
        NodeRecord beat = n;
        beat.heartbeat_us += i;
        return store_->BeatNode(beat);
      }
      if (i % 4 == 1) return store_->BeatNode(lost);
      auto s =
          store_->CreateSession("trainee-" + std::to_string(i), "arm-torsion", {"sim-0", n.epoch});
      return s.ok() ? Status::Ok() : Status(s.error());
    }));
  }
  for (int i = 0; i < 20; ++i) {
    const Status s = results[static_cast<size_t>(i)].get();
    if (i % 4 == 1)
      EXPECT_EQ(s.error().code, ErrorCode::kFailedPrecondition) << i;
    else
      EXPECT_TRUE(s.ok()) << i << ": " << s.error().message;
  }
  EXPECT_EQ(store_->LiveSessionsByNode().value(),
            (std::vector<std::pair<std::string, int>>{{"sim-0", 10}}));
}

// PostgreSQL: a node's session transaction in progress (it holds the node's row the way every
// fenced write does, until its COMMIT) does not hold up the lease's renewal, which the control
// plane writes; declaring the node down waits for it, so no write of the node straddles its fall.
// Live migration's write: a live session becomes another node's once, fenced by both nodes'
// epochs; never from a node that is down, to one that is, nor after the session ended.
TEST_P(StoreLeaseTest, ASessionMovesToAnotherNodeOnceAndOnlyBetweenLiveLeases) {
  NodeRecord a = test_store::SimNode();
  NodeRecord b = a, c = a;
  b.name = "sim-1", b.instance = "process-b";
  c.name = "sim-2", c.instance = "process-c";
  const int64_t kTimeout = 2000;
  a.epoch = store_->AcquireNode(a, kTimeout, "restarted").value().epoch;
  b.epoch = store_->AcquireNode(b, kTimeout, "restarted").value().epoch;
  c.epoch = store_->AcquireNode(c, kTimeout, "restarted").value().epoch;
  auto s = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch});
  ASSERT_TRUE(s.ok());
  ASSERT_TRUE(
      store_->SetSessionState(s->id, SessionState::kRunning, 10, "", {"sim-0", a.epoch}).ok());
  // Not from a node or epoch that does not own it; not to itself.
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-2", c.epoch}, {"sim-1", b.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-0", a.epoch + 1}, {"sim-1", b.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-0", a.epoch}, {"sim-0", a.epoch}).error().code,
            ErrorCode::kInvalidArgument);
  // Not to a node that is down.
  ASSERT_EQ(store_->MarkNodeDown("sim-2", 3000, 3000, "silent").value(), 0);
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-0", a.epoch}, {"sim-2", c.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  // Moved: the row names sim-1; its writes carry sim-1's epoch, sim-0's are refused, and it
  // does not move from sim-0 again.
  ASSERT_TRUE(store_->MoveSession(s->id, {"sim-0", a.epoch}, {"sim-1", b.epoch}).ok());
  EXPECT_EQ(store_->GetSession(s->id)->node, "sim-1");
  EXPECT_EQ(store_->GetSession(s->id)->state, SessionState::kRunning);
  EXPECT_EQ(store_->SetSessionState(s->id, SessionState::kStalled, 20, "", {"sim-0", a.epoch})
                .error()
                .code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-0", a.epoch}, {"sim-1", b.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  ASSERT_TRUE(
      store_->SetSessionState(s->id, SessionState::kStalled, 20, "", {"sim-1", b.epoch}).ok());
  // Not from a node that is down (the site aborted its sessions), nor once ended.
  auto t = store_->CreateSession("trainee-2", "arm-torsion", {"sim-1", b.epoch});
  ASSERT_TRUE(t.ok());
  ASSERT_TRUE(
      store_->SetSessionState(t->id, SessionState::kEnded, 30, "done", {"sim-1", b.epoch}).ok());
  EXPECT_EQ(store_->MoveSession(t->id, {"sim-1", b.epoch}, {"sim-0", a.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  ASSERT_EQ(store_->MarkNodeDown("sim-1", 4000, 4000, "silent").value(), 1);
  EXPECT_EQ(store_->MoveSession(s->id, {"sim-1", b.epoch}, {"sim-0", a.epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->GetSession(s->id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(s->id)->node, "sim-1");
}

// Placement across control replicas: a reservation counts on its node until the session's row
// replaces it (created there, or moved there), it is released, or it expires; the load is read
// and the choice reserved one placement at a time, so placements made at once each see the
// others'.
TEST_P(StoreLeaseTest, APlacementCountsOnceFromItsReservationToItsSessionsRow) {
  NodeRecord a = test_store::SimNode();
  NodeRecord b = a;
  b.name = "sim-1", b.instance = "process-b";
  a.epoch = store_->AcquireNode(a, 2000, "restarted").value().epoch;
  b.epoch = store_->AcquireNode(b, 2000, "restarted").value().epoch;
  const int64_t later = NowUs() + 60'000'000;
  std::map<std::string, int> load;
  const auto pick = [&load](std::optional<std::string> node) {
    return [&load, node](const std::map<std::string, int>& now) {
      load = now;
      return node;
    };
  };
  const auto load_now = [&] {
    EXPECT_FALSE(store_->ReservePlacement(later, pick(std::nullopt)).value());
    return load;
  };
  auto first = store_->ReservePlacement(later, pick("sim-0"));
  ASSERT_TRUE(first.ok() && *first) << (first.ok() ? "" : first.error().message);
  EXPECT_EQ((*first)->node, "sim-0");
  EXPECT_EQ((*first)->token.size(), 32u);
  EXPECT_TRUE(load.empty());
  auto second = store_->ReservePlacement(later, pick("sim-1")).value();
  EXPECT_EQ(load, (std::map<std::string, int>{{"sim-0", 1}}));
  // The node's row replaces the reservation: still one on sim-0.
  auto s = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch}, (*first)->token);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-0", 1}, {"sim-1", 1}}));
  // Released (the node refused): gone; releasing again changes nothing.
  ASSERT_TRUE(store_->ReleasePlacement(second->token).ok());
  ASSERT_TRUE(store_->ReleasePlacement(second->token).ok());
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-0", 1}}));
  // A moved session replaces the reservation of the node it moves to.
  ASSERT_TRUE(
      store_->SetSessionState(s->id, SessionState::kRunning, 10, "", {"sim-0", a.epoch}).ok());
  auto move = store_->ReservePlacement(later, pick("sim-1")).value();
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-0", 1}, {"sim-1", 1}}));
  ASSERT_TRUE(store_->MoveSession(s->id, {"sim-0", a.epoch}, {"sim-1", b.epoch}, move->token).ok());
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-1", 1}}));
  // A refused write keeps its reservation: the row did not replace it.
  auto kept = store_->ReservePlacement(later, pick("sim-0")).value();
  EXPECT_EQ(store_->CreateSession("trainee-2", "arm-torsion", {"sim-0", a.epoch + 1}, kept->token)
                .error()
                .code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-0", 1}, {"sim-1", 1}}));
  ASSERT_TRUE(store_->ReleasePlacement(kept->token).ok());
  // An expired reservation (its replica died mid-placement) counts no more.
  ASSERT_TRUE(store_->ReservePlacement(NowUs() - 1, pick("sim-0")).value());
  EXPECT_EQ(load_now(), (std::map<std::string, int>{{"sim-1", 1}}));
}

// Placements made at once, each choosing the least loaded of four nodes from the load it read:
// one at a time, every one sees the others', and the nodes end even.
TEST_P(StoreLeaseTest, PlacementsMadeAtOnceEachSeeTheOthers) {
  const int64_t later = NowUs() + 60'000'000;
  const auto least = [](const std::map<std::string, int>& load) {
    std::string best;
    int fewest = 1 << 30;
    for (const char* node : {"sim-0", "sim-1", "sim-2", "sim-3"}) {
      const auto it = load.find(node);
      const int n = it == load.end() ? 0 : it->second;
      if (n < fewest) best = node, fewest = n;
    }
    return std::optional<std::string>(best);
  };
  constexpr int kThreads = 4, kEach = 10;
  std::vector<std::thread> threads;
  std::atomic<int> failed{0};
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&] {
      for (int i = 0; i < kEach; ++i) failed += !store_->ReservePlacement(later, least).ok();
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(failed.load(), 0);
  std::map<std::string, int> load;
  ASSERT_TRUE(store_
                  ->ReservePlacement(later,
                                     [&](const std::map<std::string, int>& now) {
                                       load = now;
                                       return std::optional<std::string>();
                                     })
                  .ok());
  EXPECT_EQ(load, (std::map<std::string, int>{
                      {"sim-0", kEach}, {"sim-1", kEach}, {"sim-2", kEach}, {"sim-3", kEach}}));
}

TEST_P(StoreLeaseTest, ALeaseRenewalDoesNotWaitForTheNodesSessionWritesButItsFallDoes) {
  if (sqlite()) GTEST_SKIP() << "SQLite has one writer at a time: every write waits its turn";
  NodeRecord n = test_store::SimNode();
  n.epoch = store_->AcquireNode(n, 2000, "restarted").value().epoch;
  auto live = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", n.epoch});
  ASSERT_TRUE(live.ok());
  // The node's store (store_) in the middle of a session write: past its fence on the node's
  // row, waiting for the session's row, which another transaction holds.
  auto blocker = Connection::Open(path_, Connection::Mode::kReadWrite);
  ASSERT_TRUE(blocker.ok());
  Connection& b = **blocker;
  ASSERT_TRUE(b.BeginWrite().ok());
  auto hold = b.Prepare("SELECT 1 FROM sessions WHERE id = ?1 FOR UPDATE");
  ASSERT_TRUE(hold.ok());
  (*hold)->Bind(1, live->id);
  ASSERT_TRUE((*hold)->Step().value());
  (*hold)->Reset();
  auto write = std::async(std::launch::async, [&] {
    return store_->SetSessionState(live->id, SessionState::kRunning, 2000, "", {n.name, n.epoch});
  });
  auto waiting = b.Prepare(
      "SELECT count(*) FROM pg_stat_activity WHERE wait_event_type = 'Lock' AND "
      "datname = current_database()");
  ASSERT_TRUE(waiting.ok());
  const bool blocked = test::Eventually(2, [&] {
    const bool lock_wait = (*waiting)->Step().value() && (*waiting)->Int(0) > 0;
    (*waiting)->Reset();
    return lock_wait;
  });
  ASSERT_TRUE(blocked) << "the session write never reached the session's row";
  // The control plane's own store renews the lease meanwhile (a wait would end in the lock
  // timeout's error).
  auto control = Store::Open({.path = path_});
  ASSERT_TRUE(control.ok());
  n.heartbeat_us = 2000;
  const Status renewed = (*control)->BeatNode(n);
  EXPECT_TRUE(renewed.ok()) << renewed.error().message;
  EXPECT_EQ(write.wait_for(std::chrono::seconds(0)), std::future_status::timeout);
  // The fall waits for the session write in progress.
  auto fall = std::async(std::launch::async, [&] {
    return (*control)->MarkNodeDown("sim-0", 1'000'000, 3000, "silent");
  });
  EXPECT_EQ(fall.wait_for(std::chrono::milliseconds(300)), std::future_status::timeout)
      << "the node was declared down under a session write in progress";
  ASSERT_TRUE(b.Exec("ROLLBACK").ok());
  EXPECT_TRUE(write.get().ok()) << "the write, begun before the fall, completes";
  auto down = fall.get();
  ASSERT_TRUE(down.ok()) << down.error().message;
  EXPECT_EQ(down->value_or(-1), 1);
  EXPECT_EQ(store_->GetSession(live->id)->state, SessionState::kAborted);
}

TEST_P(StoreLeaseTest, NodesRegisterAndASilentNodeHasItsLiveSessionsAbortedOnce) {
  NodeRecord a{.name = "sim-0",
               .grpc_address = "10.0.0.1:7000",
               .udp_host = "10.0.0.1",
               .udp_port = 7001,
               .capacity = 24,
               .sessions = 1,
               .cpu = 0.25,
               .draining = false,
               .down = false,
               .started_us = 10,
               .heartbeat_us = 1000,
               .instance = "process-a",
               .epoch = 0};
  NodeRecord b = a;
  b.name = "sim-1";
  b.instance = "process-b";
  b.heartbeat_us = 5000;
  const int64_t kTimeout = 2000;
  a.epoch = store_->AcquireNode(a, kTimeout, "restarted").value().epoch;
  b.epoch = store_->AcquireNode(b, kTimeout, "restarted").value().epoch;
  EXPECT_EQ(a.epoch, 1);
  EXPECT_EQ(store_->AcquireNode(NodeRecord{}, kTimeout, "").error().field, "name");
  auto on_a = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch});
  auto on_b = store_->CreateSession("trainee-2", "arm-torsion", {"sim-1", b.epoch});
  auto ended_on_a = store_->CreateSession("trainee-3", "arm-torsion", {"sim-0", a.epoch});
  ASSERT_TRUE(on_a.ok() && on_b.ok() && ended_on_a.ok());
  EXPECT_EQ(on_a->node, "sim-0");
  EXPECT_EQ(store_->GetSession(on_b->id)->node, "sim-1");
  ASSERT_TRUE(
      store_->SetSessionState(ended_on_a->id, SessionState::kEnded, 50, "done", {"sim-0", a.epoch})
          .ok());
  auto by_node = store_->LiveSessionsByNode();
  ASSERT_TRUE(by_node.ok());
  EXPECT_EQ(*by_node, (std::vector<std::pair<std::string, int>>{{"sim-0", 1}, {"sim-1", 1}}));
  // A session written without its node's epoch is refused.
  EXPECT_EQ(store_->SetSessionState(on_a->id, SessionState::kRunning, 60).error().code,
            ErrorCode::kFailedPrecondition);
  b.heartbeat_us = 5500;
  ASSERT_TRUE(store_->BeatNode(b).ok());

  // sim-1 beat after the cut-off: not marked. sim-0 is silent: down, its live session aborted.
  EXPECT_FALSE(store_->MarkNodeDown("sim-1", 3000, 6000, "silent").value().has_value());
  EXPECT_EQ(store_->MarkNodeDown("sim-0", 3000, 6000, "node sim-0 stopped answering").value(), 1);
  EXPECT_FALSE(store_->MarkNodeDown("sim-0", 3000, 6001, "again").value().has_value());
  EXPECT_EQ(store_->GetSession(on_a->id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(on_a->id)->end_reason, "node sim-0 stopped answering");
  EXPECT_EQ(store_->GetSession(ended_on_a->id)->state, SessionState::kEnded);
  EXPECT_EQ(store_->GetSession(on_b->id)->state, SessionState::kCreated);
  auto nodes = store_->ListNodes();
  ASSERT_TRUE(nodes.ok());
  ASSERT_EQ(nodes->size(), 2u);
  EXPECT_TRUE((*nodes)[0].down);
  EXPECT_FALSE((*nodes)[1].down);
  EXPECT_EQ((*nodes)[1].grpc_address, "10.0.0.1:7000");
  EXPECT_EQ((*nodes)[1].cpu, 0.25);
  EXPECT_EQ((*nodes)[1].instance, "process-b");

  // The down node comes back (it was frozen): its heartbeat no longer brings it back, its
  // writes are refused and the aborted session stays aborted, with no trial recorded.
  a.heartbeat_us = 7000;
  EXPECT_EQ(store_->BeatNode(a).error().code, ErrorCode::kFailedPrecondition);
  EXPECT_TRUE(store_->ListNodes().value()[0].down);
  EXPECT_EQ(store_->SetSessionState(on_a->id, SessionState::kStalled, 7000, "", {"sim-0", a.epoch})
                .error()
                .code,
            ErrorCode::kFailedPrecondition);
  scoring::TrialMetrics ten;
  ten.score = 10;
  EXPECT_EQ(
      store_->EndSession(on_a->id, SessionState::kDisconnected, 7000, "", ten, {"sim-0", a.epoch})
          .error()
          .code,
      ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->GetSession(on_a->id)->state, SessionState::kAborted);
  EXPECT_FALSE(store_->GetTrialMetrics(on_a->id).value().has_value());
  EXPECT_EQ(store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch}).error().code,
            ErrorCode::kFailedPrecondition);

  // It acquires its name again: a new epoch; the old epoch's writes stay refused.
  const int64_t old_epoch = a.epoch;
  a.epoch = store_->AcquireNode(a, kTimeout, "restarted").value().epoch;
  EXPECT_EQ(a.epoch, old_epoch + 1);
  EXPECT_FALSE(store_->ListNodes().value()[0].down);
  EXPECT_EQ(store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", old_epoch}).error().code,
            ErrorCode::kFailedPrecondition);
  auto fresh = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch});
  ASSERT_TRUE(fresh.ok());
  EXPECT_EQ(store_->GetSession(on_b->id)->state, SessionState::kCreated);

  // A second process under a live node's name is refused, and takes nothing away.
  NodeRecord twin = a;
  twin.instance = "process-c";
  twin.grpc_address = "10.0.0.9:7000";
  twin.heartbeat_us = 7500;
  auto refused = store_->AcquireNode(twin, kTimeout, "restarted");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kAlreadyExists);
  EXPECT_NE(refused.error().message.find("process-a"), std::string::npos)
      << refused.error().message;
  EXPECT_EQ(store_->GetSession(fresh->id)->state, SessionState::kCreated);
  EXPECT_EQ(store_->ListNodes().value()[0].grpc_address, "10.0.0.1:7000");
  // Once the holder has been silent past the timeout, the name is taken: a new epoch, the
  // leftovers aborted in the same transaction, the old holder fenced.
  twin.heartbeat_us = 7000 + kTimeout + 1;
  auto taken = store_->AcquireNode(twin, kTimeout, "node restarted");
  ASSERT_TRUE(taken.ok()) << taken.error().message;
  EXPECT_EQ(taken->epoch, a.epoch + 1);
  EXPECT_EQ(taken->aborted, 1);
  EXPECT_EQ(store_->GetSession(fresh->id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(fresh->id)->end_reason, "node restarted");
  EXPECT_EQ(store_->BeatNode(a).error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->GetSession(on_b->id)->state, SessionState::kCreated);
}

}  // namespace
}  // namespace vsurg::db
