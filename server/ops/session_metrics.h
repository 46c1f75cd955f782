// The live sessions' figures for a scrape (server/ops/metrics.h): from the first scrape on it
// subscribes to the sessions' telemetry (Sessions::Subscribe, every live session, the telemetry
// rate) and keeps each one's latest sample; Collect writes the sessions by state and the
// stations' round trip, loss and haptic loop rate as families. Works over a SessionManager (one
// process, a node) and over ClusterSessions (the control plane, which then polls the nodes'
// telemetry as for a monitor: so only once something scrapes; the first scrape reads no session
// yet).
//
// Thread safety: the subscriber runs on the sessions' sampler thread; Collect on any thread.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>

#include "server/ops/metrics.h"
#include "server/session/sessions.h"

namespace vsurg::server::ops {

class SessionMetrics {
 public:
  explicit SessionMetrics(Sessions& sessions);
  ~SessionMetrics();  // unsubscribes (waits for a running call)
  SessionMetrics(const SessionMetrics&) = delete;
  SessionMetrics& operator=(const SessionMetrics&) = delete;
  void Collect(MetricsText& out);

 private:
  struct Latest {
    SessionState state = SessionState::kCreated;
    double rtt_s = 0, loss = 0, rate_hz = 0;
    uint64_t packets = 0;
  };
  Sessions& sessions_;
  std::mutex subscribe_mutex_;  // token_
  uint64_t token_ = 0;          // 0: not subscribed yet
  mutable std::mutex mutex_;    // latest_
  std::map<uint64_t, Latest> latest_;
};

}  // namespace vsurg::server::ops
