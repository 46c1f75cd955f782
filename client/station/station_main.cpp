// vsurg-station: a trainee's station. Logs in (bearer token), creates and starts a session on
// the server's control plane, streams the device over the UDP haptic channel at 1 kHz, and draws
// the deformed tissue with OpenGL: a GLFW window, or offscreen with --headless (EGL, no display)
// for tests and screenshots. Survives the server restarting (see client/station/station.h).
//
// Exit codes: 0 done, 1 runtime error (cannot connect in time, session refused), 2 usage.
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <thread>

#include <nlohmann/json.hpp>

#include "client/device/device_registry.h"
#include "client/device/virtual_hand.h"
#include "client/net/remote.h"
#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "client/station/station.h"
#include "common/core/args.h"
#include "common/core/format.h"
#include "common/core/log.h"
#include "common/core/time.h"
#include "common/geometry/bvh.h"
#include "common/scoring/proficiency.h"
#include "common/scoring/report_json.h"
#include "common/scoring/trial_metrics.h"
#include "common/sim/scene.h"
#include "common/sim/telemetry.h"
#include "common/sim/visual_model.h"

namespace {

using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;
namespace client = vsurg::client;
namespace sim = vsurg::sim;
using vsurg::Fixed;

std::atomic<bool> g_interrupted{false};
void OnSignal(int) {
  g_interrupted = true;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * (v.size() - 1))];
}

// The trial's gauges from the scene's task, the station's latest view and its link figures.
client::Guidance Guidance(const vsurg::sim::Scene& scene, const client::StationView& shown,
                          const client::StationStats& s, double live_s) {
  client::Guidance g;
  g.show = true;
  g.twist = scene.task.kind == vsurg::scoring::TaskKind::kTwist;
  g.target = scene.task.target;
  g.tolerance = scene.task.tolerance;
  g.hold_s = scene.task.hold_s;
  g.current = g.twist ? shown.command.twist : 0;
  g.force_n = shown.force.norm();
  g.force_limit_n = scene.task.force_limit;
  g.device_limit_n = scene.haptics.limits.max_force;
  g.elapsed_s = live_s;
  g.time_limit_s = scene.task.time_limit;
  // Good below the round trip at which a spring's delay is felt (2 × 36 ms one way: Rank et
  // al. 2010); poor beyond what the local model holds (docs/BENCHMARKS.md).
  const double rtt_ms = s.rtt_p50_us / 1e3;
  g.link_level = rtt_ms > 300 || s.loss > 0.10 ? 2 : rtt_ms > 72 || s.loss > 0.02 ? 1 : 0;
  g.link =
      "RTT " + Fixed(rtt_ms, rtt_ms < 10 ? 1 : 0) + " ms, " + Fixed(100 * s.loss, 1) + "% lost";
  return g;
}

// A press task's depth: how far the contact point lies below the tissue's surface at rest, m.
double PressDepth(const vsurg::geometry::Bvh& bvh, const vsurg::geometry::TriMesh& rest,
                  const client::StationView& shown) {
  if (!shown.command.contact || !shown.command.proxy.allFinite()) return 0;
  const auto hit = bvh.Closest(rest.positions, shown.command.proxy);
  return hit.triangle >= 0 ? hit.distance : 0;
}

int Fail(const std::string& what) {
  std::cerr << "vsurg-station: " << what << "\n";
  return 1;
}

// The end-of-trial summary's lines for an attempt at an exercise: each target met or missed.
struct TargetLine {
  std::string text;
};
std::vector<TargetLine> TargetLines(const client::SessionSummary& s) {
  std::vector<TargetLine> out;
  if (s.targets.empty()) return out;
  out.push_back({s.targets_passed ? "Targets: all met, a pass toward proficiency"
                                  : "Targets: not all met, not a pass"});
  for (const auto& t : s.targets) {
    const vsurg::scoring::MetricDef* def = vsurg::scoring::FindMetric(t.metric);
    const std::string label = def ? std::string(def->label) : t.metric;
    const std::string unit = def && !def->unit.empty() ? " " + std::string(def->unit) : "";
    const bool higher = def && def->better == vsurg::scoring::Better::kHigher;
    out.push_back({std::string(t.met ? "  met     " : "  missed  ") + label + " " +
                   Fixed(t.value, 2) + unit + (higher ? " (at least " : " (at most ") +
                   Fixed(t.target, 2) + unit + ")"});
  }
  return out;
}

int Run(const std::vector<std::string>& args) {
  ArgParser p("vsurg-station",
              "A trainee's station: joins a session on the server, streams the stylus over UDP "
              "at 1 kHz and draws the tissue (window, or --headless offscreen).");
  client::AddRemoteOptions(p);
  p.Option("scene", Kind::kString, "scene to train on", false, "arm-torsion")
      .Option("join", Kind::kInt, "join this session, prepared for you by an instructor")
      .Option("course", Kind::kFlag,
              "follow your course: run your next exercise (its scene, its targets; --scene is "
              "ignored) and say at the end which targets the trial met")
      .Option("exercise", Kind::kInt, "with --course: this open exercise instead of the next")
      .Option("device", Kind::kString,
              "replay, virtual-hand, keyboard-mouse, openhaptics or falcon", false, "replay")
      .Option("trajectory", Kind::kString,
              "replay: trajectory CSV (vsurg-sim trainee --out); virtual-hand: its plan")
      .Option("limits", Kind::kString, "replay, virtual-hand, keyboard-mouse: touch or omni", false,
              "touch")
      .Option("grip", Kind::kString, "virtual-hand: relaxed or tensed", false, "relaxed")
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
              false, "0")
      .Option("model-hold", Kind::kDouble,
              "seconds a contact's or grasp's local model is rendered through a silence before "
              "it fades (0: faded 20 ms into any silence)",
              false, "1")
      .Option("force-log", Kind::kString,
              "CSV of the force sent to the device per servo cycle: t_s,x_m,y_m,z_m,fx_n,fy_n,fz_n")
      .Option("rate", Kind::kDouble, "haptic rate, Hz", false, "1000")
      .Option("headless", Kind::kFlag, "render offscreen (EGL), no window")
      .Option("width", Kind::kInt, "image width, px", false, "960")
      .Option("height", Kind::kInt, "image height, px", false, "600")
      .Option("fps", Kind::kDouble, "frames per second", false, "60")
      .Option("screenshot", Kind::kString, "PNG of the last frame (or at --screenshot-at)")
      .Option("screenshot-at", Kind::kDouble, "seconds after the session starts for --screenshot")
      .Option("screenshot-before", Kind::kString, "PNG of the first frame, before any input")
      .Option("screenshot-summary", Kind::kString,
              "PNG of the end-of-trial summary (the score and what lowered it)")
      .Option("render-threads", Kind::kInt,
              "rasterizer threads of a software renderer (Mesa llvmpipe; an LP_NUM_THREADS in "
              "the environment wins): -1 two per core, 0 the driver's default (one per core), "
              "else 1..32",
              false, "-1")
      .Option("quality", Kind::kString,
              "auto (from measured frame times), low (no shadows or detail), medium or high", false,
              "auto")
      .Option("duration", Kind::kDouble, "stop after this many seconds live (0: replay end)", false,
              "0")
      .Option("settle", Kind::kDouble, "seconds to run on after the replay ends", false, "0.5")
      .Option("connect-timeout", Kind::kDouble, "give up when never connected within, s", false,
              "30")
      .Option("no-reconnect", Kind::kFlag, "end with an error when the server goes away")
      .Option("realtime-priority", Kind::kInt,
              "SCHED_FIFO priority of the haptic threads when permitted (0: off)", false, "20")
      .Option("json", Kind::kFlag, "print the summary as one JSON object");
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  if (p.Int("render-threads") < -1 || p.Int("render-threads") > 32)
    return std::cerr << "vsurg-station: --render-threads: -1, 0 or 1..32\n", 2;
  // On a software renderer the frame shares the cores with the haptic threads (and, on this
  // machine kind, the server): twice as many rasterizer threads as cores kept the frame's p99
  // lower with the server beside it (docs/BENCHMARKS.md, "Rasterizer threads"). First, while this
  // is the only thread: it sets an environment variable.
  const int render_threads = client::RequestSoftwareRenderThreads(
      p.Int("render-threads") >= 0
          ? static_cast<int>(p.Int("render-threads"))
          : static_cast<int>(std::clamp(2 * std::thread::hardware_concurrency(), 2u, 32u)));
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return vsurg::cli::UsageError(std::cerr, p.command(), remote.error());
  const double fps = p.Double("fps");
  if (!(fps >= 1 && fps <= 240)) return std::cerr << "vsurg-station: --fps: 1..240\n", 2;
  if (p.Has("screenshot-at") && !(p.Double("screenshot-at") >= 0))
    return std::cerr << "vsurg-station: --screenshot-at: must be ≥ 0\n", 2;

  // Following the course: the server says which exercise (and so which scene) comes next.
  std::optional<client::CourseExercise> exercise;
  std::string scene_name = p.String("scene");
  if (p.Has("exercise") && !p.Flag("course"))
    return std::cerr << "vsurg-station: --exercise: only with --course\n", 2;
  if (p.Flag("course")) {
    if (p.Has("join"))
      return std::cerr << "vsurg-station: --course and --join exclude each other\n", 2;
    auto next = client::NextCourseExercise(*remote, p.Has("exercise") ? p.Int("exercise") : 0,
                                           remote->timeout_s);
    if (!next.ok()) return Fail(next.error().message);
    if (!next->may_attempt) return Fail("today's attempts at '" + next->title + "' are used up");
    exercise = *next;
    scene_name = next->scene;
    std::cerr << "vsurg-station: course '" << next->course << "', exercise " << next->position
              << ". " << next->title << " (" << next->scene << "): " << next->attempts
              << " attempts, " << next->streak << " of " << next->consecutive
              << " passes in a row; targets:";
    for (const std::string& t : next->targets) std::cerr << " " << t << ";";
    std::cerr << "\n";
  }
  // The scene, as the server will run it: the same file gives the same vertex order.
  auto scene = vsurg::sim::LoadSceneByName(scene_name);
  if (!scene.ok()) return Fail("scene: " + scene.error().message);
  if (exercise && !exercise->task.empty()) {  // the exercise's task, as the server runs it
    auto task = vsurg::scoring::ApplyTaskSettings(scene->task, exercise->task);
    if (!task.ok()) return Fail("exercise task: " + task.error().message);
    scene->task = *task;
  }
  if (exercise) {
    const vsurg::scoring::TaskSpec& t = scene->task;
    const bool twist = t.kind == vsurg::scoring::TaskKind::kTwist;
    const vsurg::scoring::TaskDisplayUnit unit = vsurg::scoring::DisplayUnitOf(t.kind);
    const std::string u = std::string(" ") + unit.name;
    std::cerr << "vsurg-station: task: " << (twist ? "twist to " : "press to ")
              << vsurg::Fixed(t.target * unit.per_si, 1) << u << " within "
              << vsurg::Fixed(t.tolerance * unit.per_si, 1) << u << ", held "
              << vsurg::Fixed(t.hold_s, 1) << " s, under " << vsurg::Fixed(t.force_limit, 1)
              << " N, in " << vsurg::Fixed(t.time_limit, 0) << " s\n";
  }
  auto mesh = vsurg::sim::BuildSceneMesh(scene->mesh);
  if (!mesh.ok()) return Fail("scene mesh: " + mesh.error().message);
  auto visual = vsurg::sim::BuildVisualModel(*scene, mesh->surface);
  if (!visual.ok()) return Fail("scene visual model: " + visual.error().message);
  const std::string quality_name = p.String("quality");
  std::optional<client::Quality> fixed_quality;
  for (client::Quality q :
       {client::Quality::kLow, client::Quality::kMedium, client::Quality::kHigh})
    if (quality_name == client::QualityName(q)) fixed_quality = q;
  if (!fixed_quality && quality_name != "auto")
    return std::cerr << "vsurg-station: --quality: auto, low, medium or high\n", 2;

  // The device first (bad options are reported before any window opens); the keyboard and
  // mouse need the window, so that one is opened after it.
  client::DeviceRequest request;
  request.kind = p.String("device");
  if (p.Has("trajectory")) request.trajectory = p.String("trajectory");
  request.limits = p.String("limits");
  request.grip = p.String("grip");
  auto rendering = client::ParseLocalRendering(p.String("local-model"));
  if (!rendering.ok()) return vsurg::cli::UsageError(std::cerr, p.command(), rendering.error());
  auto passivity = client::ParsePassivityMode(p.String("passivity"));
  if (!passivity.ok()) return vsurg::cli::UsageError(std::cerr, p.command(), passivity.error());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& v : mesh->surface.positions) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  Eigen::Index longest = 0;
  (hi - lo).maxCoeff(&longest);
  request.twist_axis = Eigen::Vector3d::Unit(longest);
  request.start = 0.5 * (lo + hi);
  request.start.z() = hi.z() + 0.02;  // above the tissue
  const bool needs_window = request.kind == "keyboard-mouse";
  if (needs_window && p.Flag("headless"))
    return std::cerr << "vsurg-station: --device: keyboard-mouse needs a window (not --headless)\n",
           2;
  vsurg::Expected<std::unique_ptr<client::HapticDevice>> device =
      needs_window ? vsurg::Expected<std::unique_ptr<client::HapticDevice>>(nullptr)
                   : client::OpenDevice(request);
  if (!device.ok()) {
    std::cerr << "vsurg-station: " << device.error().field << ": " << device.error().message
              << "\n";
    return 2;
  }

  auto surface = p.Flag("headless")
                     ? client::GlSurface::CreateHeadless(p.Int("width"), p.Int("height"))
                     : client::GlSurface::CreateWindow("vsurg station: " + scene->name,
                                                       p.Int("width"), p.Int("height"));
  if (!surface.ok()) return Fail(surface.error().message);
  client::GlSurface* gl = surface->get();
  client::MeshView view(mesh->surface, std::move(*visual));
  client::QualityGovernor governor(fixed_quality.value_or(client::Quality::kHigh));
  view.SetQuality(governor.level());
  // The press depth shown: how far the contact point lies below the tissue's rest surface.
  const vsurg::geometry::Bvh rest_bvh(mesh->surface);
  if (needs_window) {
    request.window_input = [gl] { return gl->Input(); };
    device = client::OpenDevice(request);
    if (!device.ok()) return Fail(device.error().message);
  }
  auto* replay = dynamic_cast<client::ReplayDevice*>(device->get());
  auto* hand = dynamic_cast<client::VirtualHandDevice*>(device->get());
  const auto played_out = [&] {
    return (replay && replay->finished()) || (hand && hand->finished());
  };

  client::StationConfig config;
  config.scene = scene_name;
  if (exercise) config.exercise_id = exercise->exercise_id;
  if (p.Has("join")) {
    if (p.Int("join") < 1) {
      std::cerr << "vsurg-station: --join: a session id (≥ 1) is required\n";
      return 2;
    }
    config.join = static_cast<uint64_t>(p.Int("join"));
  }
  config.rate_hz = p.Double("rate");
  config.rendering = *rendering;
  config.passivity = *passivity;
  config.deadband = p.Double("deadband");
  config.force_limit_n = scene->task.force_limit;
  if (!(config.deadband >= 0 && config.deadband < 1))
    return std::cerr << "vsurg-station: --deadband: a fraction in [0, 1)\n", 2;
  config.model_hold_s = p.Double("model-hold");
  if (!(config.model_hold_s >= 0 && config.model_hold_s <= 10))
    return std::cerr << "vsurg-station: --model-hold: seconds in [0, 10]\n", 2;
  if (p.Has("force-log")) {
    config.force_log = p.String("force-log");
    // Truncated once here; each session's channel appends (one log across reconnects).
    std::FILE* f = std::fopen(config.force_log.c_str(), "w");
    if (!f)
      return std::cerr << "vsurg-station: --force-log: cannot write '" << config.force_log << "'\n",
             2;
    std::fclose(f);
  }
  config.reconnect = !p.Flag("no-reconnect");
  config.realtime_priority = p.Int("realtime-priority");
  if (config.realtime_priority < 0 || config.realtime_priority > 99)
    return std::cerr << "vsurg-station: --realtime-priority: must be within 0..99\n", 2;
  client::Station station(*remote, device->get(), config);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);

  const auto started = std::chrono::steady_clock::now();
  double live_now = 0;  // seconds live, summed over sessions
  double last_tick = 0;
  bool screenshot_taken = false, before_taken = false, ended_by_replay = false;
  double replay_done_at = -1;
  uint64_t generation = 0, last_sent = 0;
  double rate_hz = 0, last_rate_at = 0;
  client::StationStats hud_stats;  // the HUD's figures, refreshed twice a second
  client::StationView shown;
  double held_s = 0, last_frame_at = 0;  // the task's quantity within tolerance, so far
  std::vector<double> draw_ms;           // per frame: draw and finish, ms
  const auto frame = std::chrono::duration<double>(1.0 / fps);
  auto next_frame = std::chrono::steady_clock::now();
  // The session's life on its own thread: a frame that takes seconds (a first frame on a
  // software renderer, a driver's stall) does not delay noticing a lost server.
  station.StartSupervisor([](const client::StationStatus& st) {
    vsurg::LogFields fields{{"state", client::StationStateName(st.state)}, {"session", st.session}};
    if (!st.last_error.empty()) fields.emplace_back("reason", st.last_error);
    vsurg::LogEvent("vsurg-station", "state", fields);
  });
  for (;;) {
    const client::StationStatus st = station.status();
    if (st.state == client::StationState::kFailed) return Fail(st.last_error);
    if (st.generation == 0 && Seconds(started) > p.Double("connect-timeout"))
      return Fail("no session within --connect-timeout: " + st.last_error);
    const bool live = st.state == client::StationState::kLive;
    const double tick = Seconds(started);
    if (live) live_now += tick - last_tick;
    last_tick = tick;

    client::Overlay overlay;
    uint64_t channel_generation = 0, channel_session = 0;
    std::vector<vsurg::wire::SceneChunk> chunks;
    const bool refresh_hud = tick - last_rate_at >= 0.5;  // the HUD's figures, twice a second
    const bool has_channel =
        station.WithChannel([&](client::StationChannel& channel, const client::StationStatus& at) {
          channel_generation = at.generation;
          channel_session = at.session;
          chunks = channel.TakeSceneChunks();
          channel.TakeView(shown);
          if (refresh_hud) hud_stats = channel.stats();
        });
    if (has_channel) {
      if (channel_generation != generation) {
        generation = channel_generation;
        view.ResetToRest();  // a new session starts from the tissue at rest
      }
      for (const auto& chunk : chunks) view.Apply(chunk.indices, chunk.positions);
      if (refresh_hud) {
        // A new session's channel counts from zero again.
        rate_hz = last_rate_at > 0 && hud_stats.sent >= last_sent
                      ? static_cast<double>(hud_stats.sent - last_sent) / (tick - last_rate_at)
                      : 0;
        last_sent = hud_stats.sent;
        last_rate_at = tick;
      }
      const client::StationStats& s = hud_stats;
      overlay.guidance = Guidance(*scene, shown, s, live_now);
      if (!overlay.guidance.twist)
        overlay.guidance.current = PressDepth(rest_bvh, mesh->surface, shown);
      {
        const auto& g = overlay.guidance;
        const bool within =
            std::abs(std::abs(g.current) - g.target) <= g.tolerance && g.force_n <= g.force_limit_n;
        held_s = within ? held_s + (tick - last_frame_at) : 0;
        overlay.guidance.held_s = held_s;
      }
      overlay.show_stylus = true;
      overlay.tip = shown.sample.position;
      overlay.orientation = shown.sample.orientation;
      overlay.force = shown.force;
      overlay.contact = shown.command.contact;
      overlay.grasping = shown.command.grasping;
      overlay.hud = {
          "vsurg station  " + scene->name + "  session " + std::to_string(channel_session),
          sim::LinkStatus(rate_hz, s.rtt_p50_us, s.loss),
          "twist " + Fixed(shown.command.twist * 180 / M_PI, 1) + " deg   force " +
              Fixed(shown.force.norm(), 2) + " N",
          "score " + Fixed(shown.command.score, 1) + " / 10"};
      // Beyond what the local model holds faithfully (docs/BENCHMARKS.md "Haptics across
      // networks": within 20% of the no-delay force up to 300 ms round trips, 1% loss), the
      // trainee is told plainly instead of feeling a mushy tissue.
      if (s.rtt_p50_us > 300e3 || s.loss > 0.10)
        overlay.hud.push_back("LINK TOO POOR FOR FAITHFUL TOUCH: " + Fixed(s.rtt_p50_us / 1e3, 0) +
                              " ms round trip, " + Fixed(100 * s.loss, 0) +
                              "% lost (limits 300 ms, 10%)");
    } else {
      overlay.hud = {"vsurg station  " + scene->name,
                     std::string(client::StationStateName(st.state)) + " ...",
                     st.last_error.substr(0, 60)};
    }
    last_frame_at = tick;
    const auto draw_start = std::chrono::steady_clock::now();
    view.Draw(gl->width(), gl->height(), overlay);
    gl->Finish();  // the frame's whole cost, not just the commands queued
    draw_ms.push_back(1e3 * Seconds(draw_start));
    if (!fixed_quality) view.SetQuality(governor.Update(draw_ms.back()));

    if (live && !before_taken && p.Has("screenshot-before")) {
      before_taken = true;
      if (auto s = gl->SaveScreenshot(p.String("screenshot-before")); !s.ok())
        return Fail(s.error().message);
    }
    const bool at_time = p.Has("screenshot-at") && live && live_now >= p.Double("screenshot-at");
    if (p.Has("screenshot") && !screenshot_taken && at_time) {
      screenshot_taken = true;
      if (auto s = gl->SaveScreenshot(p.String("screenshot")); !s.ok())
        return Fail(s.error().message);
    }

    // When to stop: the replay played out (and settled), the time is up, the window closed, or
    // a signal. The last frame is kept for --screenshot without --screenshot-at.
    if (live && played_out() && replay_done_at < 0) replay_done_at = live_now;
    const double duration = p.Double("duration");
    bool done = g_interrupted || gl->ShouldClose();
    if (duration > 0 && live && live_now >= duration) done = true;
    if (duration <= 0 && replay_done_at >= 0 && live_now - replay_done_at >= p.Double("settle"))
      done = ended_by_replay = true;
    if (done) {
      if (p.Has("screenshot") && !screenshot_taken)
        if (auto s = gl->SaveScreenshot(p.String("screenshot")); !s.ok())
          return Fail(s.error().message);
      gl->EndFrame();
      break;
    }
    gl->EndFrame();
    next_frame += std::chrono::duration_cast<std::chrono::steady_clock::duration>(frame);
    const auto now = std::chrono::steady_clock::now();
    if (now > next_frame) next_frame = now;
    std::this_thread::sleep_until(next_frame);
  }

  const client::StationStatus st = station.status();
  const client::StationStats stats = station.total_stats();
  auto summary = station.Finish(ended_by_replay ? "completed"
                                : g_interrupted ? "interrupted"
                                                : "stopped");
  if (!summary.ok()) return Fail(summary.error().message);
  const auto& m = summary->metrics;
  // The end-of-trial summary on screen: the score and what lowered it (a window keeps it until
  // closed, or 15 s).
  if (summary->has_metrics && (p.Has("screenshot-summary") || !gl->headless())) {
    client::Overlay last;
    last.hud = {"vsurg station  " + scene->name + "  session " + std::to_string(summary->id)};
    last.summary.show = true;
    last.summary.score = m.score;
    last.summary.lines = vsurg::scoring::ExplainScore(m, scene->task);
    if (last.summary.lines.empty()) last.summary.lines = {"Nothing lowered it: expert level"};
    for (const TargetLine& line : TargetLines(*summary)) last.summary.lines.push_back(line.text);
    // A panel's size settles over its first frames (ImGui fits it to its text): the
    // screenshot is of the third.
    const auto shown_at = std::chrono::steady_clock::now();
    for (int frames = 1;; ++frames) {
      view.Draw(gl->width(), gl->height(), last);
      if (frames == 3 && p.Has("screenshot-summary")) {
        if (auto s = gl->SaveScreenshot(p.String("screenshot-summary")); !s.ok())
          return Fail(s.error().message);
      }
      gl->EndFrame();
      if (gl->headless() ? frames >= 3
                         : gl->ShouldClose() || g_interrupted || Seconds(shown_at) > 15)
        break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  if (p.Flag("json")) {
    nlohmann::json j = {{"session", summary->id},
                        {"state", SessionStateName(summary->state)},
                        {"end_reason", summary->end_reason},
                        {"reconnects", st.reconnects},
                        {"sessions", st.generation - static_cast<uint64_t>(st.moves)},
                        {"moves", st.moves},
                        {"longest_gap_ms", 1e3 * st.longest_gap_s},
                        {"sent", stats.sent},
                        {"received", stats.received},
                        {"loss", stats.loss},
                        {"lost", stats.lost},
                        {"stale", stats.stale},
                        {"duplicates", stats.duplicates},
                        {"late", stats.late},
                        {"dropped", stats.dropped},
                        {"rtt_p50_us", stats.rtt_p50_us},
                        {"rtt_p99_us", stats.rtt_p99_us},
                        {"rtt_p999_us", stats.rtt_p999_us},
                        {"jitter_us", stats.jitter_us},
                        {"energy_to_hand_j", stats.energy_to_hand},
                        {"energy_from_hand_j", stats.energy_from_hand},
                        {"passivity_dissipated_j", stats.passivity_energy_dissipated},
                        {"tissue_released_j", stats.tissue_released},
                        {"network_balance_min_j", stats.network_balance_min},
                        {"force_log_rows", stats.force_log_rows},
                        {"force_log_dropped", stats.force_log_dropped},
                        {"watchdog_fades", stats.watchdog_fades},
                        {"scene_chunks", stats.scene_chunks},
                        {"max_force_n", stats.max_force},
                        {"loop_hz", stats.loop_hz},
                        {"loop_hz_min_1s", stats.loop_hz_min},
                        {"loop_hz_max_1s", stats.loop_hz_max},
                        {"frames", draw_ms.size()},
                        {"draw_ms_p50", Percentile(draw_ms, 0.5)},
                        {"render_threads", render_threads},
                        {"draw_ms_p99", Percentile(draw_ms, 0.99)},
                        {"metrics_recorded", summary->has_metrics},
                        {"metrics", vsurg::scoring::TrialMetricsToJson(m)}};
    if (exercise) {
      nlohmann::json targets = nlohmann::json::array();
      for (const auto& t : summary->targets)
        targets.push_back(
            {{"metric", t.metric}, {"value", t.value}, {"target", t.target}, {"met", t.met}});
      j["exercise"] = {{"id", exercise->exercise_id},
                       {"title", exercise->title},
                       {"targets", targets},
                       {"passed", summary->targets_passed}};
    }
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "session " << summary->id << " " << SessionStateName(summary->state) << " ("
              << summary->end_reason << "): score " << Fixed(m.score, 1) << "/10, completed "
              << (m.completed ? "yes" : "no") << ", peak force " << Fixed(m.peak_force, 2) << " N, "
              << stats.received << "/" << stats.sent << " datagrams answered, RTT p50 "
              << Fixed(stats.rtt_p50_us, 0) << " us, " << st.reconnects << " reconnects\n";
    for (const TargetLine& line : TargetLines(*summary)) std::cout << "  " << line.text << "\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const std::exception& e) {
    std::cerr << "vsurg-station: fatal: " << e.what() << "\n";
    return 1;
  }
}
