// Control-plane messages into the core's types, for the client tools that already see the
// generated gRPC types (the station library, the admin and monitor binaries).
#pragma once

#include <cctype>
#include <string>
#include <string_view>

#include "common/scoring/trial_metrics.h"
#include "vsurg/v1/services.pb.h"

namespace vsurg::client {

// "running", "ended", … (the store's and the logs' spelling of SESSION_STATE_RUNNING, …).
inline std::string SessionStateName(v1::SessionState state) {
  std::string name = v1::SessionState_Name(state);
  constexpr std::string_view kPrefix = "SESSION_STATE_";
  if (name.rfind(kPrefix, 0) == 0) name.erase(0, kPrefix.size());
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

inline scoring::TrialMetrics TrialMetricsFromProto(const v1::TrialMetrics& m) {
  scoring::TrialMetrics out;
  out.completed = m.completed();
  out.completion_time = m.completion_time_s();
  out.task_error = m.task_error();
  out.peak_force = m.peak_force_n();
  out.time_over_force_limit = m.time_over_force_limit_s();
  out.path_length = m.path_length_m();
  out.rms_jerk = m.rms_jerk();
  out.overload_events = m.overload_events();
  out.duration = m.duration_s();
  out.score = m.score();
  out.raw_score = m.raw_score();
  out.caps = m.caps();
  return out;
}

}  // namespace vsurg::client
