// A few threads for requests that take long (a cohort's grid, a call that waits on a simulation
// node), shared fairly between the users who send them. One user's burst never starves another:
//
//  1. Each user's tasks wait in that user's own queue, at most `per_user_queued` of them; the
//     queues together hold at most `max_queued`.
//  2. A user runs at most `per_user_running` tasks at once (by default one worker fewer than
//     there are), so a free worker is left for everybody else while one user keeps every
//     connection busy.
//  3. Workers take the users with waiting work in turn (round robin), not the tasks in the order
//     they came: a user with one request waits behind at most one task of each other user.
//
// A task is told whether it runs (false: the workers are stopping; it answers and returns).
// Thread safety: Post may be called from any thread.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace vsurg::server::http {

struct FairWorkersOptions {
  int workers = 2;
  int max_queued = 32;       // over every user
  int per_user_queued = 4;   // one user's waiting tasks
  int per_user_running = 0;  // one user's tasks at once; 0: workers − 1 (at least 1)
  const char* thread_name = "vsurg-worker";
};

class FairWorkers {
 public:
  enum class Posted { kQueued, kUserBusy, kFull, kStopping };
  using Task = std::function<void(bool run)>;

  explicit FairWorkers(const FairWorkersOptions& options);
  ~FairWorkers();  // the waiting tasks are told not to run; the running ones finish
  FairWorkers(const FairWorkers&) = delete;
  FairWorkers& operator=(const FairWorkers&) = delete;

  // Queues `task` for `user`; anything but kQueued means it was not taken (and never runs).
  Posted Post(const std::string& user, Task task);

  struct Load {
    size_t queued = 0, running = 0, users = 0;
  };
  Load load() const;

 private:
  struct User {
    std::deque<Task> queue;
    int running = 0;
  };
  void Loop();
  // The next user whose turn it is and who may run one more task; end() when none.
  std::map<std::string, User>::iterator NextUser();

  const FairWorkersOptions options_;
  const int per_user_running_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, User> users_;  // users with waiting or running tasks
  std::string last_served_;            // round robin: the next turn is the user after this one
  size_t queued_ = 0, running_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace vsurg::server::http
