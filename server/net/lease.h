// A simulation node's lease on its sessions (DESIGN.md "Leases and fencing"; store.h design
// note 7). The node agent grants and renews it from the control plane's answers; the UDP
// endpoint reads it before every force, the session manager before every store write. A node
// serves a session only while it holds an unexpired lease, and the lease always ends before the
// control plane may declare the node down and place its trainees elsewhere:
//
//   valid until = (when the node *sent* the heartbeat that renewed it) + lease_s − margin
//
// on the node's own monotonic clock. The control plane declares a node down only after
// heartbeat_timeout_s (= lease_s) without a heartbeat *received*, on its own clock; receipt
// comes after sending, so neither the network's delay nor any offset between the two machines'
// wall clocks can make the two overlap (the margin covers the control replicas' disagreement
// with each other and the clocks' rates). The monotonic clock keeps running while a process is
// frozen (SIGSTOP, a paused VM), so a frozen node wakes up without a lease.
//
// Threads: Grant, Extend and Revoke from the agent's heartbeat thread; Valid and epoch from any
// thread (relaxed atomics: the deadline alone decides; the epoch changes only while the lease is
// revoked).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>

namespace vsurg::server {

class Lease {
 public:
  using Clock = std::chrono::steady_clock;

  bool Valid() const { return Valid(Clock::now()); }
  bool Valid(Clock::time_point now) const {
    return now.time_since_epoch().count() < until_.load(std::memory_order_acquire);
  }
  // The acquisition's number, carried by every store write of the sessions created under it.
  int64_t epoch() const { return epoch_.load(std::memory_order_acquire); }
  bool held() const { return epoch() > 0; }
  // Seconds of validity left at `now` (negative: lapsed; none held: −inf).
  double SecondsLeft(Clock::time_point now = Clock::now()) const {
    const int64_t until = until_.load(std::memory_order_acquire);
    if (until == 0) return -std::numeric_limits<double>::infinity();
    return std::chrono::duration<double>(Clock::duration(until) - now.time_since_epoch()).count();
  }

  // A new acquisition (epoch > 0), valid until `until`.
  void Grant(int64_t epoch, Clock::time_point until) {
    epoch_.store(epoch, std::memory_order_release);
    Extend(until);
  }
  // A renewal: never moves the deadline back (an answer that arrives out of order).
  void Extend(Clock::time_point until) {
    const int64_t t = until.time_since_epoch().count();
    int64_t cur = until_.load(std::memory_order_relaxed);
    while (t > cur && !until_.compare_exchange_weak(cur, t, std::memory_order_acq_rel)) {
    }
  }
  // Lost (the control plane refused a heartbeat): invalid at once, no epoch.
  void Revoke() {
    until_.store(0, std::memory_order_release);
    epoch_.store(0, std::memory_order_release);
  }

 private:
  std::atomic<int64_t> until_{0};  // steady clock ticks; 0: none
  std::atomic<int64_t> epoch_{0};
};

}  // namespace vsurg::server
