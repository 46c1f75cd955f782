// The haptic device a station drives (a 3- or 6-DoF stylus with force output).
//
// Units: positions in metres in the scene frame, orientation a unit quaternion, time in
// seconds, force in newtons (3-DoF force output). Read and WriteForce are called from the
// station's device thread only, at its rate (1 kHz or more); neither may block for long.
#pragma once

#include <mutex>
#include <vector>

#include "common/haptics/safety.h"
#include "common/haptics/types.h"

namespace vsurg::client {

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  // The stylus now; `time` is filled by the caller's clock if the device has none.
  virtual haptics::StylusSample Read() = 0;
  // The force to render now (N), already within limits().
  virtual void WriteForce(const Eigen::Vector3d& force) = 0;
  virtual haptics::DeviceLimits limits() const = 0;
};

// A recorded or scripted trajectory played back one sample per Read (deterministic: tests,
// demos, benchmarks). Past the end it holds the last sample. It records every force written.
class ReplayDevice : public HapticDevice {
 public:
  ReplayDevice(std::vector<haptics::StylusSample> samples,
               haptics::DeviceLimits limits = haptics::TouchLimits());
  haptics::StylusSample Read() override;
  void WriteForce(const Eigen::Vector3d& force) override;
  haptics::DeviceLimits limits() const override { return limits_; }

  // Any thread.
  std::vector<Eigen::Vector3d> forces() const;
  size_t position() const;
  bool finished() const;

 private:
  std::vector<haptics::StylusSample> samples_;
  haptics::DeviceLimits limits_;
  mutable std::mutex mutex_;  // guards the recorded forces and the cursor for readers
  size_t next_ = 0;
  std::vector<Eigen::Vector3d> forces_;
};

}  // namespace vsurg::client
