// A trial's automatic metrics (what the scoring loop reports; definitions and the score in
// common/scoring/trial_metrics.h). Light on purpose (no Eigen): the store, the wire mapping and
// the tools include it.
//
// Every boundary has one mapping of this struct: the store's columns (db/sessions_store.cpp),
// the wire (proto/convert), JSON (common/scoring/report_json.cpp).
#pragma once

#include <cstdint>

namespace vsurg::scoring {

enum ScoreCap : uint32_t {
  kCapNotCompleted = 1u << 0,
  kCapForceLimit = 1u << 1,
  kCapOverload = 1u << 2,
};

struct TrialMetrics {
  bool completed = false;
  double completion_time = 0;        // s (0 when not completed)
  double task_error = 0;             // rad or m
  double peak_force = 0;             // N
  double time_over_force_limit = 0;  // s
  double path_length = 0;            // m
  double rms_jerk = 0;               // m/s³
  int overload_events = 0;
  double duration = 0;   // s, first to last sample
  double score = 0;      // 0–10 after the gates
  double raw_score = 0;  // 0–10 before the gates
  uint32_t caps = 0;     // ScoreCap bits that applied
};

}  // namespace vsurg::scoring
