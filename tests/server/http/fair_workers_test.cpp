// The shared workers of the dashboard's long requests (server/http/fair_workers.h): one user's
// burst never takes every worker nor the whole queue, and users are served in turn.
#include "server/http/fair_workers.h"

#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/wait.h"

namespace vsurg::server::http {
namespace {

// A gate the tasks wait at until the test opens it.
class Gate {
 public:
  void Wait() {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return open_; });
  }
  void Open() {
    {
      std::lock_guard lock(m_);
      open_ = true;
    }
    cv_.notify_all();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool open_ = false;
};

TEST(FairWorkersTest, OneUsersBurstLeavesAWorkerAndTheQueueForOthers) {
  FairWorkers w({.workers = 2, .max_queued = 32, .per_user_queued = 4});
  Gate gate;
  std::atomic<int> a_started{0}, a_done{0};
  int a_busy = 0, a_queued = 0;
  // Forty requests of one instructor, each held at the gate once it runs (the first running
  // before the others come).
  for (int i = 0; i < 40; ++i) {
    const auto posted = w.Post("ian", [&](bool run) {
      if (!run) return;
      ++a_started;
      gate.Wait();
      ++a_done;
    });
    a_queued += posted == FairWorkers::Posted::kQueued;
    a_busy += posted == FairWorkers::Posted::kUserBusy;
    if (i == 0) {
      ASSERT_TRUE(test::Eventually(30, [&] { return a_started.load() == 1; }));
    }
  }
  // Another instructor's request is taken, and runs while the first one's all wait.
  std::promise<bool> b;
  ASSERT_EQ(w.Post("olga", [&](bool run) { b.set_value(run); }), FairWorkers::Posted::kQueued);
  auto ran = b.get_future();
  ASSERT_EQ(ran.wait_for(std::chrono::seconds(30)), std::future_status::ready);
  EXPECT_TRUE(ran.get());
  EXPECT_EQ(a_done.load(), 0);
  EXPECT_EQ(a_started.load(), 1);  // one worker for ian, at most (workers − 1)
  // Ian's own share: one running and four waiting; the rest refused as his (429), not 503.
  EXPECT_EQ(a_queued, 5);
  EXPECT_EQ(a_busy, 35);
  gate.Open();
  EXPECT_TRUE(test::Eventually(30, [&] { return a_done.load() == 5; }));
  EXPECT_TRUE(test::Eventually(30, [&] { return w.load().users == 0; }));
}

TEST(FairWorkersTest, UsersAreServedInTurnNotInTheOrderTheirRequestsCame) {
  FairWorkers w({.workers = 1, .max_queued = 32, .per_user_queued = 8});
  Gate gate;
  std::mutex m;
  std::vector<std::string> order;
  auto task = [&](std::string who) {
    return [&, who](bool run) {
      if (!run) return;
      if (who == "first") gate.Wait();
      std::lock_guard lock(m);
      order.push_back(who);
    };
  };
  ASSERT_EQ(w.Post("ian", task("first")), FairWorkers::Posted::kQueued);
  ASSERT_TRUE(test::Eventually(30, [&] { return w.load().running == 1; }));
  for (int i = 0; i < 3; ++i) ASSERT_EQ(w.Post("ian", task("ian")), FairWorkers::Posted::kQueued);
  ASSERT_EQ(w.Post("olga", task("olga")), FairWorkers::Posted::kQueued);
  ASSERT_EQ(w.Post("paul", task("paul")), FairWorkers::Posted::kQueued);
  gate.Open();
  ASSERT_TRUE(test::Eventually(30, [&] {
    std::lock_guard lock(m);
    return order.size() == 6;
  }));
  // After ian's running task: olga and paul, each before ian's second (turns: ian, olga, paul).
  EXPECT_EQ(order, (std::vector<std::string>{"first", "olga", "paul", "ian", "ian", "ian"}));
}

TEST(FairWorkersTest, TheQueueIsBoundedOverAllUsersAndWaitingTasksAreToldAtStop) {
  std::atomic<int> told_not_to_run{0};
  Gate gate;
  std::optional<FairWorkers> w;
  w.emplace(FairWorkersOptions{.workers = 1, .max_queued = 3, .per_user_queued = 2});
  ASSERT_EQ(w->Post("u0", [&](bool) { gate.Wait(); }), FairWorkers::Posted::kQueued);
  ASSERT_TRUE(test::Eventually(30, [&] { return w->load().running == 1; }));
  auto later = [&](bool run) { told_not_to_run += !run; };
  EXPECT_EQ(w->Post("u1", later), FairWorkers::Posted::kQueued);
  EXPECT_EQ(w->Post("u2", later), FairWorkers::Posted::kQueued);
  EXPECT_EQ(w->Post("u3", later), FairWorkers::Posted::kQueued);
  EXPECT_EQ(w->Post("u4", later), FairWorkers::Posted::kFull);
  EXPECT_EQ(w->load().queued, 3u);
  // Stopping: the three waiting are told not to run, then the running one finishes.
  std::thread opener([&] {
    EXPECT_TRUE(test::Eventually(30, [&] { return told_not_to_run.load() == 3; }));
    gate.Open();
  });
  w.reset();
  opener.join();
  EXPECT_EQ(told_not_to_run.load(), 3);
}

}  // namespace
}  // namespace vsurg::server::http
