#include "common/sim/deformation_pool.h"

#include <algorithm>
#include <string>

#include "common/core/realtime.h"

namespace vsurg::sim {

DeformationPool::DeformationPool(int workers, double poll_s)
    : poll_(std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(std::clamp(poll_s, 1e-5, 1e-2)))) {
  if (workers <= 0) workers = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads_.reserve(static_cast<size_t>(workers));
  for (int i = 0; i < workers; ++i)
    threads_.emplace_back([this, i] {
      NameThisThread(("vsurg-pool/" + std::to_string(i)).c_str());
      Work();
    });
}

DeformationPool::~DeformationPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void DeformationPool::Add(Member* m) {
  {
    std::lock_guard lock(mutex_);
    entries_.push_back({m, Clock::now(), false});
  }
  wake_.notify_one();
}

void DeformationPool::Remove(Member* m) {
  std::unique_lock lock(mutex_);
  for (;;) {
    auto it = std::find_if(entries_.begin(), entries_.end(),
                           [&](const Entry& e) { return e.member == m; });
    if (it == entries_.end()) return;
    if (!it->running) {
      entries_.erase(it);
      return;
    }
    it->leaving = true;  // a worker is stepping it: no other step, wait for this one to end
    idle_.wait(lock);
  }
}

uint64_t DeformationPool::steps() const {
  std::lock_guard lock(mutex_);
  return steps_;
}

size_t DeformationPool::members() const {
  std::lock_guard lock(mutex_);
  return entries_.size();
}

int DeformationPool::peak_busy() const {
  std::lock_guard lock(mutex_);
  return peak_busy_;
}

void DeformationPool::Work() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    // The member due earliest among those nobody steps now.
    Entry* next = nullptr;
    for (Entry& e : entries_)
      if (!e.running && !e.leaving && (!next || e.due < next->due)) next = &e;
    if (!next) {
      ++parked_;
      wake_.wait(lock);
      --parked_;
      continue;
    }
    const Clock::time_point now = Clock::now();
    if (next->due > now) {
      // Nothing due yet: sleep until it is (an Add wakes us sooner). By value: wait_until reads
      // its time again after the wait, when an Add may have moved the entries.
      const Clock::time_point until = next->due;
      wake_.wait_until(lock, until);
      continue;
    }
    next->running = true;
    Member* m = next->member;
    peak_busy_ = std::max(peak_busy_, ++busy_);
    ++steps_;
    lock.unlock();
    const Clock::time_point due = m->StepDue(now);
    lock.lock();
    --busy_;
    // The entries may have moved (an Add or a Remove of another member): find it again.
    for (Entry& e : entries_)
      if (e.member == m) {
        e.running = false;
        e.due = due;
        if (e.leaving) idle_.notify_all();
      }
    if (parked_ > 0) wake_.notify_one();  // a member is free again: a parked worker may take it
  }
}

}  // namespace vsurg::sim
