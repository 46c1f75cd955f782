#include "server/ops/collectors.h"

#include <vector>

namespace vsurg::server::ops {

void CollectEndpoint(const EndpointCounters& c, MetricsText& m) {
  m.Family("vsurg_udp_datagrams_received_total", "counter", "Datagrams the UDP endpoint read.");
  m.Sample("vsurg_udp_datagrams_received_total", {}, static_cast<double>(c.received));
  m.Family("vsurg_udp_forces_sent_total", "counter", "Force datagrams answered to stations.");
  m.Sample("vsurg_udp_forces_sent_total", {}, static_cast<double>(c.answered));
  m.Family("vsurg_udp_datagrams_dropped_total", "counter",
           "Datagrams dropped unanswered, by reason (late, fenced, bad tag, stale, ...).");
  for (size_t r = 1; r < c.dropped.size(); ++r)  // (0 is no reason)
    m.Sample("vsurg_udp_datagrams_dropped_total",
             {{"reason", wire::DropReasonName(static_cast<wire::DropReason>(r))}},
             static_cast<double>(c.dropped[r]));
  m.Family("vsurg_udp_busy_polls_total", "counter",
           "Times an I/O thread polled its socket before sleeping (--busy-poll-us).");
  m.Sample("vsurg_udp_busy_polls_total", {}, static_cast<double>(c.busy_polls));
  m.Family("vsurg_udp_busy_polled_receives_total", "counter",
           "Receives that found datagrams while the I/O thread polled instead of sleeping "
           "(--busy-poll-us).");
  m.Sample("vsurg_udp_busy_polled_receives_total", {}, static_cast<double>(c.busy_polled));
  const auto& b = EndpointCounters::kResidenceBounds;
  m.HistogramCounts("vsurg_udp_residence_seconds",
                    "Each force answer's time on the node: from its stylus datagram's arrival to "
                    "the answer's send (the node's share of the stations' round trip).",
                    {}, std::vector<double>(b.begin(), b.end()),
                    std::vector<uint64_t>(c.residence_buckets.begin(), c.residence_buckets.end()),
                    c.residence_seconds);
  m.Family("vsurg_visual_frames_sent_total", "counter", "Scene frames sent to stations.");
  m.Sample("vsurg_visual_frames_sent_total", {}, static_cast<double>(c.frames));
}

void CollectStore(const db::StoreStats& s, MetricsText& m) {
  const auto& b = db::StoreStats::kCommitBounds;
  m.HistogramCounts("vsurg_store_commit_seconds",
                    "Each group commit's time from BEGIN to COMMIT done (the store's latency for "
                    "every write it carries).",
                    {}, std::vector<double>(b.begin(), b.end()),
                    std::vector<uint64_t>(s.commit_buckets.begin(), s.commit_buckets.end()),
                    s.commit_seconds);
  m.Family("vsurg_store_jobs_total", "counter", "Write jobs the store's writer ran.");
  m.Sample("vsurg_store_jobs_total", {}, static_cast<double>(s.jobs));
  m.Family("vsurg_store_failed_jobs_total", "counter",
           "Write jobs refused or failed (a stale epoch, a constraint, a failed commit).");
  m.Sample("vsurg_store_failed_jobs_total", {}, static_cast<double>(s.failed_jobs));
  m.Family("vsurg_store_failed_commits_total", "counter",
           "Group commits whose BEGIN or COMMIT failed: the store itself (unreachable, full).");
  m.Sample("vsurg_store_failed_commits_total", {}, static_cast<double>(s.failed_commits));
  m.Family("vsurg_store_queued_jobs", "gauge", "Write jobs waiting for the writer.");
  m.Sample("vsurg_store_queued_jobs", {}, static_cast<double>(s.queued));
}

}  // namespace vsurg::server::ops
