// The OpenHaptics HD API backend (3D Systems Touch, Touch X, Phantom Premium). Compiled only when
// the SDK is found (VSURG_HAVE_OPENHAPTICS; docs/DEVICES.md): no machine of ours has one, so this
// file is built by the few that do, not by CI.
//
// The HD scheduler runs Servo() in its own thread at 1 kHz; Read and WriteForce exchange the
// latest pose and force with it through a ServoMailbox. Units at the boundary:
// HD gives millimetres in its device frame (x right, y up, z towards the user) and takes
// newtons; we give metres in the scene frame (z up), so device (x, y, z) mm → scene
// (x, −z, y) / 1000 m + offset, and forces the other way.
#include <HD/hd.h>

#include "client/device/device_registry.h"

namespace vsurg::client {
namespace {

class OpenHapticsDevice final : public HapticDevice {
 public:
  static Expected<std::unique_ptr<HapticDevice>> Open(const DeviceRequest& r) {
    std::unique_ptr<OpenHapticsDevice> d(new OpenHapticsDevice(r.scene_offset));
    d->hhd_ = hdInitDevice(r.device_name.empty() ? HD_DEFAULT_DEVICE : r.device_name.c_str());
    if (HD_DEVICE_ERROR(hdGetError()))
      return Error{ErrorCode::kUnavailable, "OpenHaptics cannot open the device", "--device"};
    HDdouble max_force = 3.3, max_stiffness_n_per_mm = 0.4, workspace_mm[6] = {0};
    hdGetDoublev(HD_NOMINAL_MAX_CONTINUOUS_FORCE, &max_force);
    hdGetDoublev(HD_NOMINAL_MAX_STIFFNESS, &max_stiffness_n_per_mm);
    hdGetDoublev(HD_USABLE_WORKSPACE_DIMENSIONS, workspace_mm);
    d->limits_.max_force = max_force;
    d->limits_.max_stiffness = max_stiffness_n_per_mm * 1000.0;  // N/mm → N/m
    const Eigen::Vector3d lo(workspace_mm[0], workspace_mm[1], workspace_mm[2]);
    const Eigen::Vector3d hi(workspace_mm[3], workspace_mm[4], workspace_mm[5]);
    const Eigen::Vector3d a = d->ToScene(lo), b = d->ToScene(hi);
    d->limits_.workspace_min = a.cwiseMin(b);
    d->limits_.workspace_max = a.cwiseMax(b);
    hdEnable(HD_FORCE_OUTPUT);
    d->callback_ =
        hdScheduleAsynchronous(&OpenHapticsDevice::Servo, d.get(), HD_DEFAULT_SCHEDULER_PRIORITY);
    hdStartScheduler();
    if (HD_DEVICE_ERROR(hdGetError()))
      return Error{ErrorCode::kUnavailable, "OpenHaptics cannot start its scheduler", "--device"};
    return std::unique_ptr<HapticDevice>(std::move(d));
  }

  ~OpenHapticsDevice() override {
    hdStopScheduler();
    hdUnschedule(callback_);
    hdDisableDevice(hhd_);
  }

  haptics::StylusSample Read() override { return mailbox_.sample(); }
  void WriteForce(const Eigen::Vector3d& force) override { mailbox_.set_force(force); }
  haptics::DeviceLimits limits() const override { return limits_; }
  DeviceInfo info() const override { return {"openhaptics", 6, 3, limits_, 1000}; }

 private:
  explicit OpenHapticsDevice(const Eigen::Vector3d& offset) : offset_(offset) {}

  Eigen::Vector3d ToScene(const Eigen::Vector3d& mm) const {
    return Eigen::Vector3d(mm.x(), -mm.z(), mm.y()) / 1000.0 + offset_;
  }

  static HDCallbackCode HDCALLBACK Servo(void* data) {
    auto* self = static_cast<OpenHapticsDevice*>(data);
    hdBeginFrame(self->hhd_);
    HDdouble position[3], transform[16];
    HDint buttons = 0;
    hdGetDoublev(HD_CURRENT_POSITION, position);
    hdGetDoublev(HD_CURRENT_TRANSFORM, transform);  // column-major, device frame
    hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);
    Eigen::Matrix3d device_rotation;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) device_rotation(r, c) = transform[4 * c + r];
    Eigen::Matrix3d to_scene;
    to_scene << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    haptics::StylusSample sample;
    sample.position = self->ToScene({position[0], position[1], position[2]});
    sample.orientation = Eigen::Quaterniond(to_scene * device_rotation).normalized();
    sample.buttons = ((buttons & HD_DEVICE_BUTTON_1) ? haptics::kButtonGrasp : 0u) |
                     ((buttons & HD_DEVICE_BUTTON_2) ? haptics::kButtonMark : 0u);
    const Eigen::Vector3d force = self->mailbox_.Exchange(sample);
    const HDdouble out[3] = {force.x(), force.z(), -force.y()};  // scene → device axes, N
    hdSetDoublev(HD_CURRENT_FORCE, out);
    hdEndFrame(self->hhd_);
    if (HD_DEVICE_ERROR(hdGetError())) return HD_CALLBACK_DONE;  // the station's watchdog fades
    return HD_CALLBACK_CONTINUE;
  }

  Eigen::Vector3d offset_;
  HHD hhd_ = HD_INVALID_HANDLE;
  HDSchedulerHandle callback_ = HD_INVALID_HANDLE;
  haptics::DeviceLimits limits_;
  ServoMailbox mailbox_;
};

}  // namespace

Expected<std::unique_ptr<HapticDevice>> OpenOpenHapticsDevice(const DeviceRequest& request) {
  return OpenHapticsDevice::Open(request);
}

}  // namespace vsurg::client
