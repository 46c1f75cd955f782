#include "client/device/device_registry.h"

#include "client/device/searching_hand.h"
#include "client/device/virtual_hand.h"
#include "common/sim/trajectory.h"

namespace vsurg::client {

std::vector<std::string> AvailableDeviceKinds() {
  std::vector<std::string> kinds = {"replay", "virtual-hand", "keyboard-mouse", "search"};
#ifdef VSURG_HAVE_OPENHAPTICS
  kinds.push_back("openhaptics");
#endif
#ifdef VSURG_HAVE_NIFALCON
  kinds.push_back("falcon");
#endif
  return kinds;
}

Expected<std::unique_ptr<HapticDevice>> OpenDevice(const DeviceRequest& r) {
  if (r.kind == "replay" || r.kind == "keyboard-mouse") {
    auto limits = haptics::DeviceLimitsByName(r.limits);
    if (!limits.ok()) return limits.error();
    if (r.kind == "replay") {
      if (r.trajectory.empty())
        return InvalidArgument("--trajectory", "the replay device needs a trajectory CSV");
      auto samples = sim::ReadTrajectoryCsv(r.trajectory);
      if (!samples.ok()) return samples.error();
      if (samples->empty()) return InvalidArgument("--trajectory", "the trajectory is empty");
      // A station replays a recording in the recording's own time.
      return std::unique_ptr<HapticDevice>(
          new ReplayDevice(std::move(*samples), *limits, ReplayDevice::Pace::kRealTime));
    }
    if (!r.window_input)
      return InvalidArgument("--device", "keyboard-mouse needs a window (not --headless)");
    return std::unique_ptr<HapticDevice>(
        new KeyboardMouseDevice(r.window_input, r.start, r.twist_axis, 0.05, *limits));
  }
  if (r.kind == "virtual-hand") {
    // The trajectory is the hand's plan; the station's force pushes the hand off it.
    auto limits = haptics::DeviceLimitsByName(r.limits);
    if (!limits.ok()) return limits.error();
    if (r.trajectory.empty())
      return InvalidArgument("--trajectory", "the virtual hand needs a plan (a trajectory CSV)");
    auto plan = sim::ReadTrajectoryCsv(r.trajectory);
    if (!plan.ok()) return plan.error();
    auto grip = GripByName(r.grip);
    if (!grip.ok()) return grip.error();
    DeviceModel model;
    model.limits = *limits;
    auto hand = VirtualHandDevice::Create(std::move(*plan), *grip, model);
    if (!hand.ok()) return hand.error();
    return std::unique_ptr<HapticDevice>(std::move(*hand));
  }
  if (r.kind == "search") {
    // A scripted examiner searching a palpation's tissue, closed on the station's forces.
    auto limits = haptics::DeviceLimitsByName(r.limits);
    if (!limits.ok()) return limits.error();
    auto style = sim::SearchStyleByName(r.search_style, "--search-style");
    if (!style.ok()) return style.error();
    auto hand = SearchingHandDevice::Create(r.rest, r.held, *style, *limits);
    if (!hand.ok()) return hand.error();
    return std::unique_ptr<HapticDevice>(std::move(*hand));
  }
  if (r.kind == "openhaptics") {
#ifdef VSURG_HAVE_OPENHAPTICS
    return OpenOpenHapticsDevice(r);
#else
    return Error{ErrorCode::kUnavailable,
                 "this build has no OpenHaptics support (the SDK was not found when it was "
                 "configured; see docs/DEVICES.md)",
                 "--device"};
#endif
  }
  if (r.kind == "falcon") {
#ifdef VSURG_HAVE_NIFALCON
    return OpenFalconDevice(r);
#else
    return Error{ErrorCode::kUnavailable,
                 "this build has no Novint Falcon support (libnifalcon was not found when it was "
                 "configured; see docs/DEVICES.md)",
                 "--device"};
#endif
  }
  return InvalidArgument("--device",
                         "unknown device '" + r.kind +
                             "' (replay, virtual-hand, keyboard-mouse, search, openhaptics, "
                             "falcon)");
}

}  // namespace vsurg::client
