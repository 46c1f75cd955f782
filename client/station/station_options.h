// vsurg-station's command line: its options (with the bounds of the StationConfig they fill),
// the checks that need no server, and the devices they ask for (the first hand's, and a second
// hand's for a scene with a second tool).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "client/device/device_registry.h"
#include "common/core/args.h"
#include "common/sim/cut_trainee.h"
#include "common/sim/scene.h"

namespace vsurg::client {

void DeclareOptions(cli::ArgParser& p);
// "vsurg-station: --option: message" on stderr; the usage exit code.
int Usage(const std::string& option, const std::string& message);
// What the options ask for that needs no server, checked before anything opens: an exit code.
std::optional<int> CheckOptions(const cli::ArgParser& p);
// The device request: the options, and where the scene's tissue is (the hand starts above its
// middle; a twist turns about its longest axis).
DeviceRequest DeviceRequestFor(const cli::ArgParser& p, const sim::Scene& scene,
                               const sim::SceneMesh& mesh);
// --second-device: grasper (the scene's scripted grasper, sim::GrasperTrainee, in real time), or
// a device of `first`'s request with its own kind, trajectory and name.
Expected<std::unique_ptr<HapticDevice>> OpenSecondDevice(const cli::ArgParser& p,
                                                         const sim::Scene& scene,
                                                         const DeviceRequest& first);

}  // namespace vsurg::client
