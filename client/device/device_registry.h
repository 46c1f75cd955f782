// Opening a device by name: the station's --device option. Real devices are plug-ins compiled
// only when their SDK is found at configure time (docs/DEVICES.md):
//   replay          a trajectory CSV (vsurg-sim trainee --out, or a recording)    always
//   virtual-hand    a simulated hand following a plan (the same CSV), pushed back by the
//                   rendered force: closed loop for tests and benchmarks            always
//   keyboard-mouse  the station's window                                         always
//   openhaptics     3D Systems Touch / Phantom through the OpenHaptics HD API
//   VSURG_HAVE_OPENHAPTICS falcon          Novint Falcon through libnifalcon VSURG_HAVE_NIFALCON
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "client/device/device.h"
#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::client {

struct DeviceRequest {
  std::string kind = "replay";
  std::string trajectory;        // replay: the CSV file
  std::string limits = "touch";  // replay, virtual-hand, keyboard-mouse: "touch" or "omni" presets
  std::string grip =
      "relaxed";  // virtual-hand: "relaxed" or "tensed" (client/device/virtual_hand.h)
  std::function<WindowInput()> window_input;              // keyboard-mouse
  Eigen::Vector3d start = Eigen::Vector3d::Zero();        // keyboard-mouse: where the tip starts, m
  Eigen::Vector3d twist_axis = Eigen::Vector3d::UnitZ();  // keyboard-mouse
  std::string device_name;  // openhaptics: the HD device name ("" = default)
  // search: the scripted examiner's style (sim::SearchStyleByName, sim::PalpationSearch), the
  // tissue's rest surface and the vertices its support holds.
  std::string search_style = "expert";
  geometry::TriMesh rest;
  std::vector<int> held;
  // Real devices: where the device's workspace centre sits in the scene frame, m.
  Eigen::Vector3d scene_offset = Eigen::Vector3d::Zero();
};

Expected<std::unique_ptr<HapticDevice>> OpenDevice(const DeviceRequest& request);
// The kinds this build can open.
std::vector<std::string> AvailableDeviceKinds();

// Plug-in entry points (defined only in builds with the SDK).
Expected<std::unique_ptr<HapticDevice>> OpenOpenHapticsDevice(const DeviceRequest& request);
Expected<std::unique_ptr<HapticDevice>> OpenFalconDevice(const DeviceRequest& request);

}  // namespace vsurg::client
