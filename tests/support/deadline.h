// For tests of "this call returns": runs `fn` on its own thread and, if it has not returned
// within `seconds`, reports the test by name and ends the process (a hung call cannot be
// cancelled, and a hang must fail the test, not wait for ctest's timeout). A sanitizer build
// (VSURG_SANITIZED) runs 10-50x slower and shares two cores with another test: it gets five
// times the time; a hang fails it all the same.
#pragma once

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <thread>
#include <utility>

#include <gtest/gtest.h>

namespace vsurg::test {

template <class Fn>
void ReturnsWithin(double seconds, const char* what, Fn&& fn) {
#ifdef VSURG_SANITIZED
  seconds *= 5;
#endif
  std::packaged_task<void()> task(std::forward<Fn>(fn));
  std::future<void> done = task.get_future();
  std::thread worker(std::move(task));
  if (done.wait_for(std::chrono::duration<double>(seconds)) != std::future_status::ready) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::fprintf(stderr, "%s.%s: %s did not return within %.0f s\n",
                 info ? info->test_suite_name() : "?", info ? info->name() : "?", what, seconds);
    std::fflush(stderr);
    std::_Exit(1);
  }
  worker.join();
  done.get();  // rethrows what fn threw
}

}  // namespace vsurg::test
