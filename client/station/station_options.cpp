// vsurg-station's command line (station_options.h): its options, their checks before anything
// opens, and the devices they ask for.
#include "client/station/station_options.h"

#include <cstdio>
#include <iostream>

#include "client/net/remote.h"
#include "client/station/instructor_controls.h"
#include "client/station/station.h"
#include "common/core/format.h"

namespace vsurg::client {

using Kind = cli::ArgParser::Kind;
using cli::ArgParser;

namespace {
void DeclareScreenOptions(ArgParser& p);
}  // namespace

void DeclareOptions(ArgParser& p) {
  using vsurg::NumberText;
  using Config = StationConfig;
  const Config defaults;
  AddRemoteOptions(p);
  p.Option("scene", Kind::kString, "scene to train on", false, defaults.scene)
      .Option("join", Kind::kInt, "join this session, prepared for you by an instructor")
      .Within({1, 2147483647})
      .Option("instruct", Kind::kInt,
              "four-handed training: join this live session of a trainee as its instructor, "
              "your hands on the trainee's tool (instructors and administrators)")
      .Within({1, 2147483647})
      .Option("mode", Kind::kString,
              "with --instruct: the mode to join in, observe (feel what the trainee feels) or "
              "guide (both hands on the tool at --alpha)",
              false, "observe")
      .Option("alpha", Kind::kDouble,
              "with --instruct: the dominance alpha of guiding, 0 (the trainee alone) to 1 (the "
              "instructor alone); the keys [ and ] change it",
              false, "0.5")
      .Within({0, 1})
      .Option("guide-plan", Kind::kString,
              "with --instruct: mode switches by seconds live, SECONDS:MODE[:ALPHA],... "
              "(\"2:guide:0.5,5:guide:1,8:guide:0\"); in a window, the keys O, G, T, H switch too")
      .Option("course", Kind::kFlag,
              "follow your course: run your next exercise (its scene, its targets; --scene is "
              "ignored) and say at the end which targets the trial met")
      .Option("exercise", Kind::kInt, "with --course: this open exercise instead of the next")
      .Option("device", Kind::kString,
              "replay, virtual-hand, keyboard-mouse, search (a scripted examiner searching a "
              "palpation's tissue), openhaptics or falcon",
              false, "replay")
      .Option("trajectory", Kind::kString,
              "replay: trajectory CSV (vsurg-sim trainee --out); virtual-hand: its plan")
      .Option("second-device", Kind::kString,
              "two hands: the second device, for a scene with a second tool (a cut scene's "
              "grasper): grasper (the scene's scripted counter-traction), replay, openhaptics or "
              "falcon")
      .Option("second-trajectory", Kind::kString, "with --second-device replay: its CSV")
      .Option("second-device-name", Kind::kString,
              "with --second-device openhaptics: the HD device name of the second stylus")
      .Option("limits", Kind::kString, "replay, virtual-hand, keyboard-mouse: touch or omni", false,
              "touch")
      .Option("grip", Kind::kString, "virtual-hand: relaxed or tensed", false, "relaxed")
      .Option("search-style", Kind::kString, "search: good, hesitant, rough, expert or novice",
              false, "expert")
      .Option("local-model", Kind::kString,
              "what is rendered between the server's answers: model (the answer's local model by "
              "its kind: contact, grasp, the surface ahead), linear (F0 + J dx everywhere) or "
              "server (the answer's force, held)",
              false, "model")
      .Option("passivity", Kind::kString,
              "local (the one-port observer on the rendering) or network (the two-port: the hand "
              "is given no more energy than the server says the tissue released)",
              false, "local")
      .Option("deadband", Kind::kDouble,
              "perceptual deadband: send the stylus only when the rendered force changed by more "
              "than this fraction of itself (Weber, ~0.1), the tip moved 0.5 mm or turned 1 deg, "
              "or 25 ms passed (15 ms while a force is rendered; 0: every cycle)",
              false, NumberText(defaults.deadband))
      .Within(Config::kDeadband)
      .Option("model-hold", Kind::kDouble,
              "seconds a contact's or grasp's local model is rendered through a silence before "
              "it fades (0: faded 20 ms into any silence)",
              false, NumberText(defaults.model_hold_s))
      .Within(Config::kModelHoldS)
      .Option("force-log", Kind::kString,
              "CSV of the force sent to the device per servo cycle: t_s,x_m,y_m,z_m,fx_n,fy_n,fz_n")
      .Option("rate", Kind::kDouble, "haptic rate, Hz", false, NumberText(defaults.rate_hz));
  DeclareScreenOptions(p);
}

namespace {

// The view's options: the window or offscreen surface, the frame rate, screenshots, quality, and
// how the trial runs out.
void DeclareScreenOptions(ArgParser& p) {
  using vsurg::NumberText;
  using Config = StationConfig;
  const Config defaults;
  p.Option("headless", Kind::kFlag, "render offscreen (EGL), no window")
      .Option("width", Kind::kInt, "image width, px", false, "960")
      .Within({16, 8192})
      .Option("height", Kind::kInt, "image height, px", false, "600")
      .Within({16, 8192})
      .Option("fps", Kind::kDouble, "frames per second", false, "60")
      .Within({1, 240})
      .Option("screenshot", Kind::kString, "PNG of the last frame (or at --screenshot-at)")
      .Option("screenshot-at", Kind::kDouble, "seconds after the session starts for --screenshot")
      .Within({0, 86400})
      .Option("screenshot-before", Kind::kString,
              "PNG of the first frame: the tissue at rest, drawn before the session is joined")
      .Option("screenshot-summary", Kind::kString,
              "PNG of the end-of-trial summary (the score and what lowered it)")
      .Option("render-threads", Kind::kInt,
              "rasterizer threads of a software renderer (Mesa llvmpipe; an LP_NUM_THREADS in "
              "the environment wins): -1 two per core, 0 the driver's default (one per core), "
              "else 1..32",
              false, "-1")
      .Within({-1, 32})
      .Option("quality", Kind::kString,
              "auto (the highest level whose frames before the trial fit the budget, lowered while "
              "frames run over it), low (no shadows or detail), medium or high",
              false, "auto")
      .Option("duration", Kind::kDouble, "stop after this many seconds live (0: replay end)", false,
              "0")
      .Option("settle", Kind::kDouble, "seconds to run on after the replay ends", false, "0.5")
      .Option("connect-timeout", Kind::kDouble, "give up when never connected within, s", false,
              "30")
      .Option("no-reconnect", Kind::kFlag, "end with an error when the server goes away")
      .Option("realtime-priority", Kind::kInt,
              "SCHED_FIFO priority of the haptic threads when permitted (0: off)", false,
              NumberText(defaults.realtime_priority))
      .Within(Config::kRealtimePriority)
      .Option("json", Kind::kFlag, "print the summary as one JSON object");
}

}  // namespace

int Usage(const std::string& option, const std::string& message) {
  std::cerr << "vsurg-station: " << (option.empty() ? "" : "--" + option + ": ") << message << "\n";
  return vsurg::cli::kExitUsage;
}

// What the options ask for that needs no server, checked before anything opens.
std::optional<int> CheckOptions(const ArgParser& p) {
  if (p.Has("exercise") && !p.Flag("course")) return Usage("exercise", "only with --course");
  if (p.Flag("course") && p.Has("join")) return Usage("", "--course and --join exclude each other");
  if (p.Has("instruct") && (p.Flag("course") || p.Has("join")))
    return Usage("instruct", "an instructor joins another's session: not with --course or --join");
  for (const char* only : {"mode", "alpha", "guide-plan"})
    if (p.Has(only) && !p.Has("instruct")) return Usage(only, "only with --instruct");
  if (auto plan = ParseGuidePlan(p.String("guide-plan")); !plan.ok())
    return Usage("guide-plan", plan.error().field + ": " + plan.error().message);
  if (p.String("device") == "keyboard-mouse" && p.Flag("headless"))
    return Usage("device", "keyboard-mouse needs a window (not --headless)");
  for (const char* only : {"second-trajectory", "second-device-name"})
    if (p.Has(only) && !p.Has("second-device")) return Usage(only, "only with --second-device");
  if (p.Has("second-device") && p.Has("instruct"))
    return Usage("second-device", "an instructor joins with one hand");
  if (p.Has("force-log")) {
    // Truncated once here; each session's channel appends (one log across reconnects).
    std::FILE* f = std::fopen(p.String("force-log").c_str(), "w");
    if (!f) return Usage("force-log", "cannot write '" + p.String("force-log") + "'");
    std::fclose(f);
  }
  return std::nullopt;
}

// The device request: the options, and where the scene's tissue is (the hand starts above its
// middle; a twist turns about its longest axis).
DeviceRequest DeviceRequestFor(const ArgParser& p, const sim::Scene& scene,
                               const sim::SceneMesh& mesh) {
  const vsurg::geometry::TriMesh& surface = mesh.surface;
  DeviceRequest request;
  request.kind = p.String("device");
  request.search_style = p.String("search-style");
  if (request.kind == "search") {
    request.rest = surface;
    if (auto held = sim::SupportedVertices(surface, scene.region, mesh.groups); held.ok())
      request.held = std::move(*held);
  }
  if (p.Has("trajectory")) request.trajectory = p.String("trajectory");
  request.limits = p.String("limits");
  request.grip = p.String("grip");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& v : surface.positions) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  Eigen::Index longest = 0;
  (hi - lo).maxCoeff(&longest);
  request.twist_axis = Eigen::Vector3d::Unit(longest);
  request.start = 0.5 * (lo + hi);
  request.start.z() = hi.z() + 0.02;  // above the tissue
  return request;
}

Expected<std::unique_ptr<HapticDevice>> OpenSecondDevice(const ArgParser& p,
                                                         const sim::Scene& scene,
                                                         const DeviceRequest& first) {
  const std::string kind = p.String("second-device");
  if (kind == "grasper") {
    auto plan = sim::GrasperTrainee(scene);
    if (!plan.ok()) return InvalidArgument("--second-device", plan.error().message);
    return std::unique_ptr<HapticDevice>(std::make_unique<ReplayDevice>(
        std::move(*plan), first.limits == "omni" ? haptics::OmniLimits() : haptics::TouchLimits(),
        ReplayDevice::Pace::kRealTime));
  }
  if (kind == "keyboard-mouse" || kind == "virtual-hand" || kind == "search")
    return InvalidArgument("--second-device", "grasper, replay, openhaptics or falcon");
  DeviceRequest request = first;
  request.kind = kind;
  request.trajectory = p.Has("second-trajectory") ? p.String("second-trajectory") : "";
  request.device_name = p.Has("second-device-name") ? p.String("second-device-name") : "";
  return OpenDevice(request);
}

}  // namespace vsurg::client
