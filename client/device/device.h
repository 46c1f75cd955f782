// The haptic device a station drives (a 3- or 6-DoF stylus with force output), after
// OpenSurgSim's input/output contract (SurgSim/Input/OutputProducerInterface.h).
//
// Units: positions in metres in the scene frame, orientation a unit quaternion (the stylus
// frame in the scene frame; its +z runs from the tip back along the shaft), time in seconds,
// force in newtons (3-DoF force output), buttons as haptics::StylusButton bits. A device maps
// its own workspace (millimetres, its own axes) into the scene frame itself.
//
// Threads: Read and WriteForce are called from the station's device thread only, at its rate
// (1 kHz or more), and neither may block for long. info() from any thread.
//
// Backends: ReplayDevice (a trajectory; deterministic: tests, the demo, benchmarks),
// KeyboardMouseDevice (the station's window), and the real devices in device_registry.h,
// compiled only when their SDK is found (docs/DEVICES.md).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "client/device/window_input.h"
#include "common/core/clock.h"
#include "common/haptics/safety.h"
#include "common/haptics/types.h"

namespace vsurg::client {

// What a device is and may do.
struct DeviceInfo {
  std::string name;              // "replay", "keyboard-mouse", "openhaptics", …
  int input_dof = 6;             // 3: position only; 6: position and orientation
  int output_dof = 3;            // force axes (no device here renders torque)
  haptics::DeviceLimits limits;  // max force (N), force rate (N/s), stiffness (N/m), workspace (m)
  double rate_hz = 1000;         // the servo rate it is meant to run at
};

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  virtual DeviceInfo info() const { return {"device", 6, 3, limits(), 1000}; }
  // The stylus now; `time` is filled by the caller's clock if the device has none.
  virtual haptics::StylusSample Read() = 0;
  // The force to render now (N), already within limits().
  virtual void WriteForce(const Eigen::Vector3d& force) = 0;
  virtual haptics::DeviceLimits limits() const = 0;
};

// What a real device's own servo thread (its SDK's) and the station's device thread share: the
// newest pose one way, the newest force the other, under a mutex held for a copy.
class ServoMailbox {
 public:
  // The SDK's servo thread: publishes the pose it read, takes the force to output (N).
  Eigen::Vector3d Exchange(const haptics::StylusSample& sample);
  // The station's device thread.
  haptics::StylusSample sample() const;
  void set_force(const Eigen::Vector3d& force);

 private:
  mutable std::mutex mutex_;
  haptics::StylusSample sample_;
  Eigen::Vector3d force_ = Eigen::Vector3d::Zero();
};

// A recorded or scripted trajectory played back. Two paces:
//  - kPerRead: one sample per Read, whatever the time (deterministic: tests, benchmarks);
//  - kRealTime: by the samples' own times from the first Read, the pose interpolated between
//    samples (linear, slerp; buttons of the earlier one), as a hand would have moved: a station
//    whose loop runs late reads where the hand is now, not the next sample in the file (which
//    would put a late cycle's catch-up burst into the trial's velocity and jerk).
// Past the end it holds the last sample. It records every force written.
class ReplayDevice : public HapticDevice {
 public:
  enum class Pace { kPerRead, kRealTime };
  // kRealTime reads `clock` (null: the steady clock), which must outlive the device.
  ReplayDevice(std::vector<haptics::StylusSample> samples,
               haptics::DeviceLimits limits = haptics::TouchLimits(), Pace pace = Pace::kPerRead,
               const Clock* clock = nullptr);
  haptics::StylusSample Read() override;
  void WriteForce(const Eigen::Vector3d& force) override;
  haptics::DeviceLimits limits() const override { return limits_; }
  DeviceInfo info() const override { return {"replay", 6, 3, limits_, 1000}; }

  // Any thread.
  std::vector<Eigen::Vector3d> forces() const;
  size_t position() const;
  bool finished() const;

 private:
  std::vector<haptics::StylusSample> samples_;
  haptics::DeviceLimits limits_;
  Pace pace_;
  const Clock& clock_;
  mutable std::mutex mutex_;  // guards the recorded forces and the cursor for readers
  size_t next_ = 0;           // kPerRead: the next sample; kRealTime: the first one not yet due
  double start_s_ = -1;       // kRealTime: the clock at the first Read
  std::vector<Eigen::Vector3d> forces_;
};

// The window's keyboard and mouse as a 6-DoF stylus without force output (the force is only
// drawn): keys move the tip at `speed` m/s along the scene axes, a right-button drag twists the
// stylus about `twist_axis`, space or the left button holds the grasp button. `input` is polled
// on the device thread (GlSurface::Input is thread-safe).

class KeyboardMouseDevice : public HapticDevice {
 public:
  KeyboardMouseDevice(std::function<WindowInput()> input, Eigen::Vector3d start,
                      Eigen::Vector3d twist_axis = Eigen::Vector3d::UnitZ(), double speed = 0.05,
                      haptics::DeviceLimits limits = haptics::TouchLimits(),
                      const Clock* clock = nullptr);  // null: the steady clock
  haptics::StylusSample Read() override;
  void WriteForce(const Eigen::Vector3d& force) override;
  haptics::DeviceLimits limits() const override { return limits_; }
  DeviceInfo info() const override { return {"keyboard-mouse", 6, 0, limits_, 1000}; }
  Eigen::Vector3d last_force() const;

 private:
  std::function<WindowInput()> input_;
  Eigen::Vector3d position_, axis_;
  double speed_;
  haptics::DeviceLimits limits_;
  const Clock& clock_;
  double last_time_ = -1;
  mutable std::mutex mutex_;
  Eigen::Vector3d force_ = Eigen::Vector3d::Zero();
};

}  // namespace vsurg::client
