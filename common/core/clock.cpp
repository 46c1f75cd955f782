#include "common/core/clock.h"

#include <chrono>

namespace vsurg {

double SteadyClock::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

const Clock& DefaultClock() {
  static const SteadyClock clock;
  return clock;
}

}  // namespace vsurg
