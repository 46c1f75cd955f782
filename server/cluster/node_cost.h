// What a simulation node holds: its cores (those it may run on, within its cgroup's CPU quota)
// and, at its scenes' measured cost per station (Scene::core_per_station), the live sessions that
// 70% of them take, the node's default --capacity (docs/SCALING.md, "Capacity from the cost").
#pragma once

#include <string>

namespace vsurg::server {

// The cores this process may use: its CPU affinity, capped by a cgroup v2 quota (cpu.max, as a
// container's CPU limit sets it), rounded up; at least 1.
double NodeCores();

// The dearest scene in `dir` that states its cost, and how many of its scenes do.
struct DearestScene {
  std::string name;             // empty when no scene states a cost
  double core_per_station = 0;  // cores
  int scenes = 0, stated = 0;
};
DearestScene FindDearestScene(const std::string& dir);

// The sessions `share` of `cores` hold at `core_per_station` each, within [1, 4096]; 0 when the
// cost is not known (≤ 0).
int CapacityAtCost(double cores, double core_per_station, double share = 0.7);

}  // namespace vsurg::server
