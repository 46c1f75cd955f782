#include "server/ops/session_metrics.h"

#include <array>
#include <vector>

namespace vsurg::server::ops {

SessionMetrics::SessionMetrics(Sessions& sessions) : sessions_(sessions) {}

SessionMetrics::~SessionMetrics() {
  std::lock_guard lock(subscribe_mutex_);
  if (token_) sessions_.Unsubscribe(token_);
}

void SessionMetrics::Collect(MetricsText& out) {
  {
    std::lock_guard lock(subscribe_mutex_);
    if (!token_) {
      // Every call carries every live session: the map is rebuilt from it.
      token_ = sessions_.Subscribe(0, [this](const std::vector<SessionTelemetry>& all, bool) {
        std::map<uint64_t, Latest> now;
        for (const SessionTelemetry& t : all)
          if (IsLive(t.state))
            now[t.id] = {t.state, t.rtt_us * 1e-6, t.packet_loss, t.haptic_rate_hz, t.packets};
        std::lock_guard inner(mutex_);
        latest_.swap(now);
      });
    }
  }
  std::array<int, 3> by_state{};  // created, running, stalled
  std::vector<double> rtt, loss, rate;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, l] : latest_) {
      if (l.state == SessionState::kCreated) ++by_state[0];
      if (l.state == SessionState::kRunning) ++by_state[1];
      if (l.state == SessionState::kStalled) ++by_state[2];
      if (l.state != SessionState::kRunning || l.packets == 0) continue;  // a driven station
      rtt.push_back(l.rtt_s);
      loss.push_back(l.loss);
      if (l.rate_hz > 0) rate.push_back(l.rate_hz);
    }
  }
  out.Family("vsurg_sessions_live", "gauge", "Live sessions by state.");
  const char* names[] = {"created", "running", "stalled"};
  for (size_t i = 0; i < 3; ++i)
    out.Sample("vsurg_sessions_live", {{"state", names[i]}}, by_state[i]);
  out.Family("vsurg_stations_driving", "gauge", "Stations driving a running session now.");
  out.Sample("vsurg_stations_driving", {}, static_cast<double>(rtt.size()));
  out.Histogram("vsurg_station_rtt_seconds",
                "Each driving station's last reported haptic round trip (stylus to force).", {},
                {0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5}, rtt);
  out.Histogram("vsurg_station_loss_ratio",
                "Each driving station's stylus datagrams lost (sequence gaps) over those sent.", {},
                {0.001, 0.01, 0.05, 0.1, 0.25, 0.5}, loss);
  out.Histogram("vsurg_station_haptic_rate_hz",
                "Each driving station's haptic loop rate (samples per second of its clock); "
                "below 900 Hz the loop overran.",
                {}, {250, 500, 900, 990, 1010, 2000}, rate);
}

}  // namespace vsurg::server::ops
