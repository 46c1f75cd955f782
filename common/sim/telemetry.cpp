#include "common/sim/telemetry.h"

#include <cmath>

#include "common/core/format.h"

namespace vsurg::sim {

std::array<TelemetryField, kTelemetryFieldCount> TelemetryFields(const SessionTelemetry& t) {
  using K = TelemetryField::Kind;
  const Telemetry& s = t.sim;
  auto count = [](uint64_t n) { return static_cast<double>(n); };
  return {{
      {"time_s", s.time, K::kReal, 3},
      {"force_n", s.force.norm(), K::kReal, 2},
      {"twist_deg", s.twist * 180.0 / M_PI, K::kReal, 1},
      {"torque_nm", s.torque, K::kReal, 4},
      {"depth_mm", s.depth * 1000.0, K::kReal, 1},
      {"contact", s.contact ? 1.0 : 0.0, K::kFlag, 0},
      {"grasping", s.grasping ? 1.0 : 0.0, K::kFlag, 0},
      {"samples", count(s.samples), K::kCount, 0},
      {"clock_jumps", count(s.clock_jumps), K::kCount, 0},
      {"score", s.metrics.score, K::kReal, 1},
      {"overload_events", static_cast<double>(s.metrics.overload_events), K::kCount, 0},
      {"peak_force_n", s.metrics.peak_force, K::kReal, 2},
      {"over_limit_s", s.metrics.time_over_force_limit, K::kReal, 2},
      {"rtt_us", t.rtt_us, K::kReal, 0},
      {"loss_ratio", t.packet_loss, K::kReal, 4},
      {"packets", count(t.packets), K::kCount, 0},
      {"haptic_rate_hz", t.haptic_rate_hz, K::kReal, 0},
      {"guide_mode", static_cast<double>(s.guide_mode), K::kCount, 0},
      {"dominance_ratio", s.guide_alpha, K::kReal, 2},
      {"hands_apart_mm", s.hands_apart * 1000.0, K::kReal, 1},
      // The hands on the tool, in the scene's frame (the dashboard draws both): the trainee's tip,
      // and the instructor's while one is on the tool (at the origin otherwise).
      {"tip_x_mm", s.tip.x() * 1000.0, K::kReal, 2},
      {"tip_y_mm", s.tip.y() * 1000.0, K::kReal, 2},
      {"tip_z_mm", s.tip.z() * 1000.0, K::kReal, 2},
      {"instructor", s.instructor ? 1.0 : 0.0, K::kFlag, 0},
      {"instructor_x_mm", s.instructor ? s.instructor_tip.x() * 1000.0 : 0.0, K::kReal, 2},
      {"instructor_y_mm", s.instructor ? s.instructor_tip.y() * 1000.0 : 0.0, K::kReal, 2},
      {"instructor_z_mm", s.instructor ? s.instructor_tip.z() * 1000.0 : 0.0, K::kReal, 2},
  }};
}

std::string TelemetryText(const SessionTelemetry& t) {
  std::string line;
  for (const TelemetryField& f : TelemetryFields(t)) {
    if (!line.empty()) line += ' ';
    line += f.name;
    line += '=';
    line += Fixed(f.value, f.decimals);
  }
  return line;
}

std::string LinkStatus(double haptic_rate_hz, double rtt_us, double loss_ratio) {
  return "haptic " + Fixed(haptic_rate_hz, 0) + " Hz   RTT " + Fixed(rtt_us, 0) + " µs   loss " +
         Fixed(100 * loss_ratio, 1) + "%";
}

}  // namespace vsurg::sim
