#include "server/session/caller_deadline.h"

#include <algorithm>

namespace vsurg::server {
namespace {

thread_local std::chrono::system_clock::time_point caller_deadline =
    std::chrono::system_clock::time_point::max();

}  // namespace

CallerDeadline::CallerDeadline(std::chrono::system_clock::time_point at)
    : previous_(caller_deadline) {
  caller_deadline = std::min(at, previous_);
}

CallerDeadline::~CallerDeadline() {
  caller_deadline = previous_;
}

double CallerDeadline::Left(double cap_s) {
  if (caller_deadline == std::chrono::system_clock::time_point::max()) return cap_s;
  const double left =
      std::chrono::duration<double>(caller_deadline - std::chrono::system_clock::now()).count();
  return std::min(std::max(left, 1e-3), cap_s);
}

bool CallerDeadline::Passed() {
  return caller_deadline != std::chrono::system_clock::time_point::max() &&
         std::chrono::system_clock::now() >= caller_deadline;
}

}  // namespace vsurg::server
