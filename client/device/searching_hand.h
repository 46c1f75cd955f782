// A scripted examiner's hand at a station (sim::PalpationSearch): it searches a palpation's
// tissue for lumps closed on the forces the station renders to it, and presses the mark button
// where it finds one, so a whole palpation (the network, the station's local model, the server's
// case and scoring) runs without a person. Exact positions, as the replay device's; its time is
// the clock's since the first Read (the network runs in real time).
//
// Threads: Read and WriteForce from the station's device thread; finished() from any thread.
#pragma once

#include <atomic>
#include <mutex>

#include "client/device/device.h"
#include "common/core/clock.h"
#include "common/sim/palpation_search.h"

namespace vsurg::client {

class SearchingHandDevice : public HapticDevice {
 public:
  // `rest`: the tissue's surface at rest, `held`: its vertices the scene's support holds.
  static Expected<std::unique_ptr<SearchingHandDevice>> Create(
      const geometry::TriMesh& rest, const std::vector<int>& held, const sim::SearchStyle& style,
      haptics::DeviceLimits limits = haptics::TouchLimits(), const Clock* clock = nullptr);

  haptics::StylusSample Read() override;
  void WriteForce(const Eigen::Vector3d& force) override;
  haptics::DeviceLimits limits() const override { return limits_; }
  DeviceInfo info() const override { return {"search", 3, 3, limits_, 1000}; }
  bool finished() const { return finished_.load(); }

 private:
  SearchingHandDevice(sim::PalpationSearch search, haptics::DeviceLimits limits,
                      const Clock* clock);
  sim::PalpationSearch search_;
  haptics::DeviceLimits limits_;
  const Clock& clock_;
  double start_s_ = -1;
  std::mutex mutex_;
  haptics::ForceCommand last_;  // the force written last, as the search reads it
  bool has_force_ = false;
  std::atomic<bool> finished_{false};
};

}  // namespace vsurg::client
