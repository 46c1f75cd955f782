#include "client/device/searching_hand.h"

namespace vsurg::client {

Expected<std::unique_ptr<SearchingHandDevice>> SearchingHandDevice::Create(
    const geometry::TriMesh& rest, const std::vector<int>& held, const sim::SearchStyle& style,
    haptics::DeviceLimits limits, const Clock* clock) {
  auto search = sim::PalpationSearch::Create(rest, held, style);
  if (!search.ok()) return search.error();
  return std::unique_ptr<SearchingHandDevice>(
      new SearchingHandDevice(std::move(*search), limits, clock));
}

SearchingHandDevice::SearchingHandDevice(sim::PalpationSearch search, haptics::DeviceLimits limits,
                                         const Clock* clock)
    : search_(std::move(search)), limits_(limits), clock_(clock ? *clock : DefaultClock()) {}

haptics::StylusSample SearchingHandDevice::Read() {
  const double now = clock_.Now();
  if (start_s_ < 0) start_s_ = now;
  haptics::ForceCommand last;
  bool has = false;
  {
    std::lock_guard lock(mutex_);
    last = last_;
    has = has_force_;
  }
  haptics::StylusSample s = search_.Next(now - start_s_, has ? &last : nullptr);
  s.time = now;
  if (search_.done()) finished_.store(true);
  return s;
}

void SearchingHandDevice::WriteForce(const Eigen::Vector3d& force) {
  std::lock_guard lock(mutex_);
  last_.force = force;
  has_force_ = true;
}

}  // namespace vsurg::client
