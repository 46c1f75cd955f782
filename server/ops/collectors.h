// The figures each part of the server already keeps, as Prometheus families (server/ops/
// metrics.h): the UDP haptic endpoint's counters and the store's writer. Called by the scrape's
// collectors (server_main.cpp), never on the haptic path.
#pragma once

#include "db/store.h"
#include "server/net/udp_endpoint.h"
#include "server/ops/metrics.h"

namespace vsurg::server::ops {

// Datagrams received, forces answered, drops by reason, visual frames.
void CollectEndpoint(const EndpointCounters& c, MetricsText& m);
// Group commits and their latency, jobs, failed jobs and failed commits (the store itself), the
// writer's queue.
void CollectStore(const db::StoreStats& s, MetricsText& m);

}  // namespace vsurg::server::ops
