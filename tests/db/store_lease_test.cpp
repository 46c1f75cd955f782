// A node's lease in the store: renewing it is one request to a shared store (the control plane
// renews every node's lease every few seconds), and a renewal of a lost lease is refused.
#include <future>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "db/store.h"
#include "tests/db/store_fixture.h"

namespace vsurg::db {
namespace {

class StoreLeaseTest : public test_store::StoreTest {};

INSTANTIATE_TEST_SUITE_P(Backends, StoreLeaseTest,
                         ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& p) { return std::string(BackendName(p.param)); });

TEST_P(StoreLeaseTest, ALeaseRenewalIsOneRoundTrip) {
  NodeRecord n{.name = "sim-0",
               .grpc_address = "10.0.0.1:7000",
               .udp_host = "10.0.0.1",
               .udp_port = 7001,
               .capacity = 24,
               .heartbeat_us = 1000,
               .instance = "process-a"};
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
  NodeRecord n{.name = "sim-0",
               .grpc_address = "10.0.0.1:7000",
               .udp_host = "10.0.0.1",
               .udp_port = 7001,
               .capacity = 24,
               .heartbeat_us = 1000,
               .instance = "process-a"};
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

}  // namespace
}  // namespace vsurg::db
