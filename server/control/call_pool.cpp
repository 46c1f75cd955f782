#include "server/control/call_pool.h"

#include <algorithm>

#include "common/core/realtime.h"

namespace vsurg::server {

CallPool::CallPool(int max_threads) : max_threads_(std::max(1, max_threads)) {}

CallPool::~CallPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  ready_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void CallPool::Post(std::function<void()> task) {
  std::lock_guard lock(mutex_);
  tasks_.push_back(std::move(task));
  // A thread for this task unless one is idle to take it (an idle thread that has been woken
  // but has not taken its task yet still counts as idle, so a burst starts one thread per task).
  if (idle_ >= static_cast<int>(tasks_.size()) ||
      static_cast<int>(threads_.size()) >= max_threads_) {
    ready_.notify_one();
    return;
  }
  threads_.emplace_back([this] {
    NameThisThread("vsurg-rpc-pool");
    Work();
  });
  ready_.notify_one();
}

int CallPool::threads() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(threads_.size());
}

void CallPool::Work() {
  std::unique_lock lock(mutex_);
  for (;;) {
    ++idle_;
    ready_.wait(lock, [&] { return stopping_ || !tasks_.empty(); });
    --idle_;
    if (tasks_.empty()) return;  // stopping, and nothing left to run
    std::function<void()> task = std::move(tasks_.front());
    tasks_.pop_front();
    lock.unlock();
    task();
    lock.lock();
  }
}

}  // namespace vsurg::server
