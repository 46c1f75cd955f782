// A thread's own set-up. TrySetRealtimePriority runs a haptic thread ahead of everything else on
// the machine: SCHED_FIFO at `priority` (1–99) for the calling thread, as OpenHaptics runs its
// servo loop. Needs root or CAP_SYS_NICE; without them the thread keeps the normal policy and this
// returns false. Only for threads that sleep or block every cycle (the 1 kHz loops), which
// therefore cannot starve the machine. NameThisThread names it for an operator's tools.
#pragma once

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cstring>

namespace vsurg {

inline bool TrySetRealtimePriority(int priority) {
  if (priority <= 0) return false;
  sched_param param{};
  param.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

// Names the calling thread as `top -H`, `ps -L`, `perf` and gdb show it ("vsurg-io/0"). Linux
// keeps 15 characters; a longer name is cut to them.
inline void NameThisThread(const char* name) {
  char cut[16] = {};
  std::memcpy(cut, name, std::min<size_t>(std::strlen(name), sizeof cut - 1));
  pthread_setname_np(pthread_self(), cut);
}

}  // namespace vsurg
