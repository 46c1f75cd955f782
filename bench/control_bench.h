// vsurg-bench control-plane commands: durable gRPC submissions per second, and export speed.
#pragma once

#include <string>
#include <vector>

namespace vsurg::bench {

int GrpcSubmit(const std::vector<std::string>& args);
int ExportBench(const std::vector<std::string>& args);
// Session creation through the control role's placement against the all-in-one path.
int Placement(const std::vector<std::string>& args);
// The control plane's store writes for many simulated nodes' heartbeats, written or in memory.
int Heartbeats(const std::vector<std::string>& args);
// What a control replica receives for its telemetry watchers: the former poll against the streams.
int TelemetryBench(const std::vector<std::string>& args);

}  // namespace vsurg::bench
