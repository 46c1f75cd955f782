// Deformation for many live simulations on a few threads (a node's many stations): one worker
// per core instead of a thread per session, so 64 or 128 driven sessions are two workers on a
// 2-core node, not 64 or 128 threads contending with the haptic I/O thread for the same cores.
// The haptic path never waits on the pool: it publishes its input exactly as it does for a
// simulation's own deformation thread.
//
// Scheduling: each member says when it is next due (a dynamic model every dt of its scene; a
// quasi-static one, coil or reduced, when its haptic side asked for something new). A worker
// takes, among the members no other worker is stepping, the one due earliest, and sleeps until
// the earliest due time when none is due yet. The choice is a linear scan under one mutex: a node
// holds a few hundred members at most, and a scan of 128 is well under a microsecond. Quasi-static
// members are polled every `poll_s` rather than woken, so the haptic thread makes no system call
// for them; their deformation follows a request within poll_s (visual frames go out at 60 Hz).
//
// Threads: Add and Remove from control threads (never a worker, never the haptic thread).
// Remove returns once no worker is stepping the member, and none will again. Members must be
// removed before they are destroyed; the pool must outlive its members' removal.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace vsurg::sim {

class DeformationPool {
 public:
  using Clock = std::chrono::steady_clock;

  class Member {
   public:
    virtual ~Member() = default;
    // On a worker, never concurrently with itself: does what is due at `now` and returns when
    // the member is next due.
    virtual Clock::time_point StepDue(Clock::time_point now) = 0;
  };

  // `workers` 0: one per core (std::thread::hardware_concurrency). `poll_s`: how often a member
  // that has nothing to do is looked at again (see above); 1e-5 to 0.01 s.
  explicit DeformationPool(int workers = 0, double poll_s = 5e-4);
  ~DeformationPool();  // joins the workers; every member must have been removed
  DeformationPool(const DeformationPool&) = delete;
  DeformationPool& operator=(const DeformationPool&) = delete;

  void Add(Member* m);  // due at once
  void Remove(Member* m);

  int workers() const { return static_cast<int>(threads_.size()); }
  Clock::duration poll() const { return poll_; }
  uint64_t steps() const;  // StepDue calls so far
  size_t members() const;  // members now
  int peak_busy() const;   // the most workers ever stepping at once (tests)

 private:
  struct Entry {
    Member* member = nullptr;
    Clock::time_point due;
    bool running = false;
    bool leaving = false;  // Remove waits for its step to end: never picked again
  };
  void Work();

  const Clock::duration poll_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;  // a member added, or stop
  std::condition_variable idle_;  // a step finished (Remove waits on it)
  std::vector<Entry> entries_;
  uint64_t steps_ = 0;
  int busy_ = 0, peak_busy_ = 0;
  int parked_ = 0;  // workers asleep with every member taken (woken when one is free again)
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace vsurg::sim
