// Monotonic time in seconds, injectable. What decides by elapsed time (the UDP endpoint's stall
// and disconnect timeouts and rate limit, the station channel's fade and link-loss timers, a
// replay device's pace) reads a Clock: the steady clock in the programs, a ManualClock in tests,
// which then advance time instead of sleeping and stop assuming how fast the scheduler runs.
//
// Thread safety: Now() may be called from any thread; ManualClock's setters too.
#pragma once

#include <atomic>

namespace vsurg {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual double Now() const = 0;  // s, monotonic; the origin is the clock's own
};

// std::chrono::steady_clock.
class SteadyClock final : public Clock {
 public:
  double Now() const override;
};

// The process's steady clock (what a component uses when given none).
const Clock& DefaultClock();

// Time that moves only when told to.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(double start_s = 0) : now_(start_s) {}
  double Now() const override { return now_.load(std::memory_order_acquire); }
  void Set(double s) { now_.store(s, std::memory_order_release); }
  void Advance(double ds) { Set(Now() + ds); }

 private:
  std::atomic<double> now_;
};

}  // namespace vsurg
