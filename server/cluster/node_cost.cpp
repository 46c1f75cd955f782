#include "server/cluster/node_cost.h"

#include <sched.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "common/sim/scene.h"

namespace vsurg::server {

double NodeCores() {
  double cores = 1;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) cores = std::max(1, CPU_COUNT(&set));
  // "max 100000" (no limit) or "<quota> <period>", microseconds.
  std::ifstream in("/sys/fs/cgroup/cpu.max");
  std::string quota;
  double period = 0;
  if (in >> quota >> period && quota != "max" && period > 0) {
    const double limit = std::ceil(std::strtod(quota.c_str(), nullptr) / period);
    if (limit >= 1) cores = std::min(cores, limit);
  }
  return cores;
}

DearestScene FindDearestScene(const std::string& dir) {
  DearestScene d;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(dir, error)) {
    if (entry.path().extension() != ".json") continue;
    auto scene = sim::LoadScene(entry.path().string());
    if (!scene.ok()) continue;  // the catalog names it; it runs no session here
    ++d.scenes;
    if (scene->core_per_station <= 0) continue;
    ++d.stated;
    if (scene->core_per_station > d.core_per_station)
      d.core_per_station = scene->core_per_station, d.name = entry.path().stem().string();
  }
  return d;
}

int CapacityAtCost(double cores, double core_per_station, double share) {
  if (!(core_per_station > 0) || !(cores > 0)) return 0;
  const double n = std::floor(share * cores / core_per_station + 1e-9);  // 1.4 / 0.28 is 5
  return static_cast<int>(std::clamp(n, 1.0, 4096.0));
}

}  // namespace vsurg::server
