#include "proto/convert/services.h"

namespace vsurg::convert {

v1::SessionState ToProto(SessionState s) {
  return static_cast<v1::SessionState>(static_cast<int>(s));
}

std::optional<SessionState> FromProto(v1::SessionState s) {
  return SessionStateFromNumber(static_cast<int>(s));
}

std::string StateName(v1::SessionState s) {
  const auto state = FromProto(s);
  return state ? SessionStateName(*state) : "unspecified";
}

void ToProto(const scoring::TrialMetrics& m, v1::TrialMetrics* out) {
  out->set_completed(m.completed);
  out->set_completion_time_s(m.completion_time);
  out->set_task_error(m.task_error);
  out->set_peak_force_n(m.peak_force);
  out->set_time_over_force_limit_s(m.time_over_force_limit);
  out->set_path_length_m(m.path_length);
  out->set_rms_jerk(m.rms_jerk);
  out->set_overload_events(m.overload_events);
  out->set_duration_s(m.duration);
  out->set_score(m.score);
  out->set_raw_score(m.raw_score);
  out->set_caps(m.caps);
  out->set_station_peak_force_n(m.link.station_peak_force);
  out->set_station_time_over_limit_s(m.link.station_time_over_limit);
  out->set_link_rtt_ms(m.link.rtt_ms);
  out->set_link_jitter_ms(m.link.jitter_ms);
  out->set_link_loss_ratio(m.link.loss);
  out->set_link_rate_hz(m.link.rate_hz);
}

scoring::TrialMetrics FromProto(const v1::TrialMetrics& m) {
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
  out.link.station_peak_force = m.station_peak_force_n();
  out.link.station_time_over_limit = m.station_time_over_limit_s();
  out.link.rtt_ms = m.link_rtt_ms();
  out.link.jitter_ms = m.link_jitter_ms();
  out.link.loss = m.link_loss_ratio();
  out.link.rate_hz = m.link_rate_hz();
  return out;
}

}  // namespace vsurg::convert
