// Waiting on progress instead of sleeping a guess: Eventually polls a condition until it holds or
// a bound passes. The bound is a liveness limit, never a timing goal (those live in benchmarks):
// generous, and five times longer in a sanitizer build (VSURG_SANITIZED), as ReturnsWithin.
#pragma once

#include <chrono>
#include <thread>

namespace vsurg::test {

// True as soon as `done()` holds; false if it still does not after `seconds`. Polls every `poll`.
template <class Pred>
bool Eventually(double seconds, Pred&& done,
                std::chrono::milliseconds poll = std::chrono::milliseconds(5)) {
#ifdef VSURG_SANITIZED
  seconds *= 5;
#endif
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() >= until) return done();
    std::this_thread::sleep_for(poll);
  }
  return true;
}

}  // namespace vsurg::test
