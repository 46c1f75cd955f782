// The control plane's call pool (server/control/call_pool.h) and the caller's deadline
// (server/session/caller_deadline.h), alone: tasks that wait do not hold up the next, the pool
// stops growing at its bound and queues, and ending it runs what was queued.
#include "server/control/call_pool.h"
#include "server/session/caller_deadline.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>

#include <gtest/gtest.h>

#include "tests/support/wait.h"

namespace vsurg::server {
namespace {

// A gate the tasks wait at until the test opens it.
class Gate {
 public:
  void Wait() {
    std::unique_lock lock(mutex_);
    ++waiting_;
    cv_.wait(lock, [&] { return open_; });
  }
  void Open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    cv_.notify_all();
  }
  int waiting() {
    std::lock_guard lock(mutex_);
    return waiting_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  int waiting_ = 0;
  bool open_ = false;
};

TEST(CallPoolTest, TasksThatWaitDoNotHoldUpTheNextAndTheBoundQueuesTheRest) {
  Gate gate;
  std::atomic<int> ran{0};
  {
    CallPool pool(8);
    // Twenty tasks that wait: the first eight each get a thread at once, the rest queue.
    for (int i = 0; i < 20; ++i)
      pool.Post([&] {
        gate.Wait();
        ++ran;
      });
    ASSERT_TRUE(test::Eventually(30, [&] { return gate.waiting() == 8; }));
    EXPECT_EQ(pool.threads(), 8);
    EXPECT_EQ(ran, 0);
    gate.Open();
    ASSERT_TRUE(test::Eventually(30, [&] { return ran == 20; }));
    EXPECT_EQ(pool.threads(), 8);
    // Idle threads take new work instead of new ones starting.
    for (int i = 0; i < 8; ++i) pool.Post([&] { ++ran; });
    ASSERT_TRUE(test::Eventually(30, [&] { return ran == 28; }));
    EXPECT_EQ(pool.threads(), 8);
  }
}

TEST(CallPoolTest, EndingThePoolRunsWhatWasQueued) {
  std::atomic<int> ran{0};
  Gate gate;
  {
    CallPool pool(1);
    pool.Post([&] { gate.Wait(); });
    for (int i = 0; i < 5; ++i) pool.Post([&] { ++ran; });
    ASSERT_TRUE(test::Eventually(30, [&] { return gate.waiting() == 1; }));
    EXPECT_EQ(ran, 0);
    gate.Open();
  }  // joins after the queue is empty
  EXPECT_EQ(ran, 5);
}

TEST(CallerDeadlineTest, BoundsANodeCallByTheCallersDeadlineOnlyWithinItsScope) {
  EXPECT_EQ(CallerDeadline::Left(5), 5);  // outside a call: the node call's own timeout
  {
    const CallerDeadline outer(std::chrono::system_clock::now() + std::chrono::seconds(2));
    EXPECT_LE(CallerDeadline::Left(5), 2);
    EXPECT_GT(CallerDeadline::Left(5), 0);
    EXPECT_EQ(CallerDeadline::Left(0.5), 0.5);  // the node call's own timeout when shorter
    {
      // A caller that has gone: a millisecond, never "no deadline".
      const CallerDeadline gone(std::chrono::system_clock::now() - std::chrono::seconds(1));
      EXPECT_EQ(CallerDeadline::Left(5), 1e-3);
    }
    {
      // A nested scope never extends the outer deadline.
      const CallerDeadline later(std::chrono::system_clock::now() + std::chrono::hours(1));
      EXPECT_LE(CallerDeadline::Left(5), 2);
    }
    EXPECT_LE(CallerDeadline::Left(5), 2);
  }
  EXPECT_EQ(CallerDeadline::Left(5), 5);
}

}  // namespace
}  // namespace vsurg::server
