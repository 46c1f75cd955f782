// How long the user call this thread serves may still run (the control plane sets it around a
// call's body, server/control/grpc_common.h). A node call made on the caller's behalf that only
// reads (ClusterSessions::Join, a surface, a record) ends when its caller stops waiting, not a
// full call_timeout_s later: a frozen node's Join then holds a control-plane thread for the
// station's 1 s, not for 5 s after the station has asked again.
#pragma once

#include <chrono>

namespace vsurg::server {

class CallerDeadline {
 public:
  explicit CallerDeadline(std::chrono::system_clock::time_point at);  // for this scope
  ~CallerDeadline();                                                  // the one before again
  CallerDeadline(const CallerDeadline&) = delete;
  CallerDeadline& operator=(const CallerDeadline&) = delete;

  // Seconds the caller still waits, at most `cap_s` (`cap_s` outside a call; 1 ms when the
  // caller has already gone, so the node call fails at once instead of having no deadline).
  static double Left(double cap_s);
  // The caller has stopped waiting (a deadline is set and it has passed).
  static bool Passed();

 private:
  std::chrono::system_clock::time_point previous_;
};

}  // namespace vsurg::server
