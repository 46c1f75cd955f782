// The Novint Falcon through libnifalcon (3-DoF in, 3-DoF out). Compiled only when libnifalcon is
// found (VSURG_HAVE_NIFALCON; docs/DEVICES.md): no machine of ours has one, so CI does not
// build this file.
//
// libnifalcon has no scheduler of its own: a thread here runs its I/O loop at 1 kHz. The
// Falcon reports metres in its own frame (x right, y up, z towards the grip's rest at ≈ 0.125 m);
// the scene frame has z up: device (x, y, z − 0.125) → scene (x, −(z − 0.125), y) + offset.
#include <falcon/core/FalconDevice.h>
#include <falcon/firmware/FalconFirmwareNovintSDK.h>
#include <falcon/grip/FalconGripFourButton.h>
#include <falcon/kinematic/FalconKinematicStamper.h>

#include <atomic>
#include <thread>

#include "client/device/device_registry.h"
#include "common/core/realtime.h"

namespace vsurg::client {
namespace {

constexpr double kRestZ = 0.125;  // m, the grip's centre of travel along the device z

class FalconHapticDevice final : public HapticDevice {
 public:
  static Expected<std::unique_ptr<HapticDevice>> Open(const DeviceRequest& r) {
    std::unique_ptr<FalconHapticDevice> d(new FalconHapticDevice(r.scene_offset));
    d->falcon_.setFalconFirmware<libnifalcon::FalconFirmwareNovintSDK>();
    d->falcon_.setFalconKinematic<libnifalcon::FalconKinematicStamper>();
    d->falcon_.setFalconGrip<libnifalcon::FalconGripFourButton>();
    if (!d->falcon_.open(0))
      return Error{ErrorCode::kUnavailable, "libnifalcon cannot open Falcon 0", "--device"};
    if (!d->falcon_.isFirmwareLoaded())
      return Error{ErrorCode::kUnavailable,
                   "the Falcon's firmware is not loaded (run findfalcons from libnifalcon)",
                   "--device"};
    d->limits_.max_force = 8.9;  // N, Novint's rating
    d->limits_.max_stiffness = 1000;
    d->limits_.workspace_min = r.scene_offset - Eigen::Vector3d::Constant(0.05);
    d->limits_.workspace_max = r.scene_offset + Eigen::Vector3d::Constant(0.05);
    d->thread_ = std::thread([p = d.get()] {
      NameThisThread("vsurg-falcon");
      p->Loop();
    });
    return std::unique_ptr<HapticDevice>(std::move(d));
  }

  ~FalconHapticDevice() override {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    falcon_.setForce({0, 0, 0});
    falcon_.runIOLoop();
    falcon_.close();
  }

  haptics::StylusSample Read() override { return mailbox_.sample(); }
  void WriteForce(const Eigen::Vector3d& force) override { mailbox_.set_force(force); }
  haptics::DeviceLimits limits() const override { return limits_; }
  DeviceInfo info() const override { return {"falcon", 3, 3, limits_, 1000}; }

 private:
  explicit FalconHapticDevice(const Eigen::Vector3d& offset) : offset_(offset) {}

  void Loop() {
    while (!stop_) {
      if (falcon_.runIOLoop()) {
        const std::array<double, 3> p = falcon_.getPosition();
        const unsigned buttons = falcon_.getFalconGrip()->getDigitalInputs();
        haptics::StylusSample sample;
        sample.position = Eigen::Vector3d(p[0], -(p[2] - kRestZ), p[1]) + offset_;
        sample.buttons = ((buttons & 1u) ? haptics::kButtonGrasp : 0u) |
                         ((buttons & 2u) ? haptics::kButtonMark : 0u);
        const Eigen::Vector3d f = mailbox_.Exchange(sample);
        falcon_.setForce({f.x(), f.z(), -f.y()});
      }
      std::this_thread::sleep_for(std::chrono::microseconds(1000));
    }
  }

  Eigen::Vector3d offset_;
  libnifalcon::FalconDevice falcon_;
  haptics::DeviceLimits limits_;
  ServoMailbox mailbox_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace

Expected<std::unique_ptr<HapticDevice>> OpenFalconDevice(const DeviceRequest& request) {
  return FalconHapticDevice::Open(request);
}

}  // namespace vsurg::client
