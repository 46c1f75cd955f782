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
  kCapBackWall = 1u << 3,  // a needle through its target's back wall (needle.h)
};

// What the station rendered and how the link held over the trial, recorded beside the server's
// own figures so a score is never blind to what the trainee actually felt (haptics across
// networks). Zero when the station did not report them (one older than this field).
struct LinkFigures {
  double station_peak_force = 0;       // N, the largest force the station sent to its device
  double station_time_over_limit = 0;  // s, … above the task's force limit
  double rtt_ms = 0;                   // the station's last reported round trip
  double jitter_ms = 0;                // mean |RTT_i − RTT_{i−1}|, as the station measured it
  double loss = 0;                     // stylus datagrams the server never applied, 0..1
  double rate_hz = 0;                  // stylus datagrams applied per second
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
  // Four-handed training: the share of the trial's time an instructor's hand was on the tool
  // (dominance α > 0), 0..1, and the mean α over that time. The other figures are the trainee's
  // own work: their hand's path, their share of the tissue's force.
  double guided_share = 0;
  double guided_alpha = 0;
  // A palpation (palpation.h): the lumps hidden, those found, the marks that found none, the mean
  // distance from a found lump to its mark (m), the share of the surface examined (0..1) and the
  // mean force in contact (N). Zero for the other tasks.
  int lumps = 0, lumps_found = 0, false_marks = 0;
  double localisation_error = 0, coverage = 0, mean_force = 0;
  // A needle insertion (needle.h): the tip's distance from the target's middle along its tract
  // (m), the tract's distance from the target's centre or axis (m), the boundaries punctured and
  // those beyond the final tract's own, the back walls passed through, the largest lateral strain
  // of the tract. Zero for the other tasks.
  double depth_error = 0, path_deviation = 0, lateral_strain = 0;
  int punctures = 0, extra_punctures = 0, back_wall_breaches = 0;
  // A pattern cut (cut.h): the cut's largest distance from the marked pattern (its RMS is
  // task_error, the share of the pattern cut within the band is coverage), the length cut outside
  // the band and the length torn by pulling instead of cut (m), and the blade's lifts mid-cut.
  // Zero for the other tasks.
  double cut_deviation_max = 0, cut_outside = 0, torn_length = 0;
  int cut_lifts = 0;
  LinkFigures link;  // filled by the server that ran the session (not by the recorder)
};

}  // namespace vsurg::scoring
