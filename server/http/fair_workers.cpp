#include "server/http/fair_workers.h"

#include <algorithm>

#include "common/core/realtime.h"

namespace vsurg::server::http {

FairWorkers::FairWorkers(const FairWorkersOptions& options)
    : options_(options),
      per_user_running_(options.per_user_running > 0 ? options.per_user_running
                                                     : std::max(1, options.workers - 1)) {
  for (int i = 0; i < std::max(1, options_.workers); ++i)
    threads_.emplace_back([this] {
      NameThisThread(options_.thread_name);
      Loop();
    });
}

FairWorkers::~FairWorkers() {
  std::vector<Task> left;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    for (auto& [name, user] : users_)
      for (Task& task : user.queue) left.push_back(std::move(task));
    for (auto& [name, user] : users_) user.queue.clear();
    queued_ = 0;
  }
  cv_.notify_all();
  for (Task& task : left) task(false);
  for (std::thread& t : threads_) t.join();
}

FairWorkers::Posted FairWorkers::Post(const std::string& user, Task task) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return Posted::kStopping;
    User& u = users_[user];
    if (u.queue.size() >= static_cast<size_t>(std::max(1, options_.per_user_queued))) {
      if (u.running == 0 && u.queue.empty()) users_.erase(user);
      return Posted::kUserBusy;
    }
    if (queued_ >= static_cast<size_t>(std::max(1, options_.max_queued))) {
      if (u.running == 0 && u.queue.empty()) users_.erase(user);
      return Posted::kFull;
    }
    u.queue.push_back(std::move(task));
    ++queued_;
  }
  cv_.notify_one();
  return Posted::kQueued;
}

FairWorkers::Load FairWorkers::load() const {
  std::lock_guard lock(mutex_);
  return Load{queued_, running_, users_.size()};
}

std::map<std::string, FairWorkers::User>::iterator FairWorkers::NextUser() {
  // The users after the last one served, then from the first: each in turn.
  auto start = users_.upper_bound(last_served_);
  for (size_t n = 0, size = users_.size(); n < size; ++n, ++start) {
    if (start == users_.end()) start = users_.begin();
    if (!start->second.queue.empty() && start->second.running < per_user_running_) return start;
  }
  return users_.end();
}

void FairWorkers::Loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    auto next = users_.end();
    cv_.wait(lock, [&] { return stopping_ || (next = NextUser()) != users_.end(); });
    if (stopping_) return;
    const std::string name = next->first;
    Task task = std::move(next->second.queue.front());
    next->second.queue.pop_front();
    ++next->second.running;
    --queued_;
    ++running_;
    last_served_ = name;
    lock.unlock();
    task(true);
    lock.lock();
    --running_;
    User& u = users_[name];
    if (--u.running == 0 && u.queue.empty()) users_.erase(name);
    // The user may run another task now, and a worker waiting on the per-user bound may go.
    cv_.notify_all();
  }
}

}  // namespace vsurg::server::http
