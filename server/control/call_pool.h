// The threads the control plane's unary calls run on (server/control/grpc_common.h, Unary).
//
// gRPC's callback API runs every handler on a few threads of its own: gRPC 1.51 (Debian's) runs
// them on its CallbackAlternativeCQ, clamp(cores / 2, 2, 16) threads, two on a two-core node. A
// handler that waits, a node building a scene for Create or a frozen node's Join until its
// deadline, held one of those two, and two such calls stalled every call on the replica for
// seconds, a station's cheap probe (SessionService/Get) included: on a loaded site the stations
// of a killed node then gave up on a control plane that was only busy (seen in the site's e2e
// test: six of eight stations back after 5 s instead of 1). Here the bodies run on threads that
// may wait: a pool that starts a thread whenever none is idle, up to `max_threads`, then queues,
// as gRPC's synchronous server does with its own. boost::asio::thread_pool is fixed in size,
// which would move the stall from two threads to N, so this is our own (about 60 lines).
//
// A call's wait on a node is also bounded by its caller's deadline (server/session/
// caller_deadline.h), so a thread is not held after its caller has gone.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace vsurg::server {

class CallPool {
 public:
  explicit CallPool(int max_threads = 128);
  ~CallPool();  // runs what is queued, then joins every thread
  CallPool(const CallPool&) = delete;
  CallPool& operator=(const CallPool&) = delete;

  void Post(std::function<void()> task);
  int threads() const;  // started so far (they stay, idle, until the pool ends)

 private:
  void Work();

  const int max_threads_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> tasks_;
  std::vector<std::thread> threads_;
  int idle_ = 0;
  bool stopping_ = false;
};

}  // namespace vsurg::server
