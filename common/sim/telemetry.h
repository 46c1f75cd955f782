// A session's telemetry: what the simulation reports of its last sample (Telemetry), what the
// server adds about the session and its link (SessionTelemetry), and the one mapping of a sample
// to named numbers (TelemetryFields), each name carrying its unit, from which the dashboard's JSON
// and the monitor's text line are both written. The proto mapping is in proto/convert.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/session_state.h"
#include "common/geometry/mesh.h"
#include "common/scoring/metrics.h"

namespace vsurg::sim {

// What an instructor's monitor shows of a session (units as in haptics::ForceCommand).
struct Telemetry {
  double time = 0;                                // s, the station's clock of the last sample
  geometry::Vec3 force = geometry::Vec3::Zero();  // N, sent to the device
  geometry::Vec3 tip = geometry::Vec3::Zero();    // m, the stylus tip of that sample
  double twist = 0;                               // rad
  double torque = 0;                              // N·m
  double depth = 0;                               // m, press depth (press scenes; else 0)
  bool contact = false, grasping = false;
  uint64_t samples = 0;           // stylus samples handled
  uint64_t clock_jumps = 0;       // samples whose time jumped (haptics::kEventClockJump)
  scoring::TrialMetrics metrics;  // so far
  // Four-handed training (guidance.h): the mode (GuideMode's value), the dominance α now, and
  // the instructor's hand (m) and its distance from the trainee's (m) while one is on the tool.
  uint32_t guide_mode = 0;
  double guide_alpha = 0;
  bool instructor = false;
  geometry::Vec3 instructor_tip = geometry::Vec3::Zero();
  double hands_apart = 0;
  // The tool the tissue met (the trainee's tip while nobody guides) and the tissue's force on it
  // before the hands' shares (N).
  geometry::Vec3 tool = geometry::Vec3::Zero();
  geometry::Vec3 tool_force = geometry::Vec3::Zero();
};

// One live session's sample as the control plane hands it on (gRPC Watch, the dashboard's
// event streams, a simulation node to the control plane).
struct SessionTelemetry {
  uint64_t id = 0;
  SessionState state = SessionState::kCreated;
  int64_t server_time_us = 0;
  Telemetry sim;
  double rtt_us = 0;
  double packet_loss = 0;  // lost / (applied + lost)
  uint64_t packets = 0;
  // The station's haptic loop rate: stylus samples applied per second of the station's own clock
  // (the stamps it sends), over windows of ≥ 1 s, refreshed once a window; 0 unless running.
  double haptic_rate_hz = 0;
  std::string scene;
  std::string trainee;
  // Every third sample (10 Hz at the default rate): the deformed surface for monitors, as the
  // vertices away from rest (sim::Simulation::ShownSurface).
  bool has_surface = false;
  uint64_t surface_frame = 0;
  std::vector<int32_t> surface_indices;
  std::vector<geometry::Vec3> surface_positions;
};

// One number of a sample: its name with the unit (`force_n`, `time_s`, `loss_ratio`; counts,
// flags and the 0–10 score have none), its value in that unit, and the decimals a person reads.
struct TelemetryField {
  enum class Kind { kReal, kCount, kFlag };
  std::string_view name;
  double value;
  Kind kind;
  int decimals;
};
constexpr size_t kTelemetryFieldCount = 27;
// The sample's numbers in a fixed order (non-finite values as they are: each writer decides).
std::array<TelemetryField, kTelemetryFieldCount> TelemetryFields(const SessionTelemetry& t);

// "name=value" for every field, space-separated (the monitor's text line).
std::string TelemetryText(const SessionTelemetry& t);

// The link as a trainee or an instructor reads it: "haptic 1000 Hz   RTT 412 µs   loss 0.0%".
std::string LinkStatus(double haptic_rate_hz, double rtt_us, double loss_ratio);

}  // namespace vsurg::sim
