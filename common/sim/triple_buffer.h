// Lock-free single-producer single-consumer "latest value" hand-off (a triple buffer).
//
// The producer fills Back() and calls Publish(); the consumer calls Acquire() and reads
// Front(). Neither ever blocks or waits for the other, the consumer always sees a complete
// value (the newest published when it acquired), and no value is copied through a lock. Three
// slots: one the producer writes, one the consumer reads, one in the middle, swapped by a single
// atomic exchange on each side.
//
// Invariants: back_, front_ and (middle_ & 3) are always a permutation of {0, 1, 2}; only the
// producer touches back_, only the consumer front_; the dirty bit is set by Publish and cleared
// by Acquire.
#pragma once

#include <atomic>
#include <cstdint>

namespace vsurg::sim {

template <class T>
class TripleBuffer {
 public:
  // Producer thread.
  T& Back() { return slots_[back_]; }
  void Publish() { back_ = middle_.exchange(back_ | kDirty, std::memory_order_acq_rel) & kIndex; }

  // Consumer thread. True when a newer value became Front().
  bool Acquire() {
    if ((middle_.load(std::memory_order_relaxed) & kDirty) == 0) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    return true;
  }
  const T& Front() const { return slots_[front_]; }
  T& Front() { return slots_[front_]; }  // the consumer's own until its next Acquire

  // Set-up only (no thread running): the same value in every slot.
  template <class F>
  void ForEachSlot(F&& f) {
    for (T& s : slots_) f(s);
  }

 private:
  static constexpr uint32_t kIndex = 3, kDirty = 4;
  T slots_[3];
  uint32_t back_ = 0, front_ = 1;
  std::atomic<uint32_t> middle_{2};
};

}  // namespace vsurg::sim
