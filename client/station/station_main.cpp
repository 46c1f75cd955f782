// vsurg-station: a trainee's station. Logs in (bearer token), creates and starts a session on
// the server's control plane, streams the device over the UDP haptic channel at 1 kHz, and draws
// the deformed tissue with OpenGL: a GLFW window, or offscreen with --headless (EGL, no display)
// for tests and screenshots. Survives the server restarting (see client/station/station.h).
//
// Exit codes: 0 done, 1 runtime error (cannot connect in time, session refused), 2 usage.
#include <signal.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <optional>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/device/device_registry.h"
#include "client/device/searching_hand.h"
#include "client/device/virtual_hand.h"
#include "client/net/remote.h"
#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "client/station/coil_twist_view.h"
#include "client/station/instructor_controls.h"
#include "client/station/station.h"
#include "client/station/station_options.h"
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
using vsurg::client::CheckOptions;
using vsurg::client::DeclareOptions;
using vsurg::client::DeviceRequestFor;
using vsurg::client::Usage;
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
  g.palpate = scene.task.kind == vsurg::scoring::TaskKind::kPalpate;
  g.marks = static_cast<int>(s.marks);
  g.target = scene.task.target;
  g.tolerance = scene.task.tolerance;
  g.hold_s = scene.task.hold_s;
  g.current = g.twist ? shown.command.twist : 0;
  g.needle = scene.task.kind == vsurg::scoring::TaskKind::kInsert;
  if (const auto& n = shown.command.local.needle;
      g.needle && n.phase != vsurg::haptics::NeedleState::Phase::kFree) {
    g.current = std::max(0.0, (shown.sample.position - n.entry).dot(n.direction));
    g.passed = static_cast<int>(n.passed);
  }
  if (scene.cut) {
    g.cut = true;
    g.current = scene.cut->pattern.Distance(shown.sample.position.x(), shown.sample.position.y());
    // The answer's local model is the patch's out-of-plane spring while the blade presses on it,
    // none once it is through (Simulation::CutStep).
    g.through = shown.command.contact && shown.command.local.jacobian.isZero();
  }
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

// Following the course: the server says which exercise (and so which scene) comes next.
vsurg::Expected<std::optional<client::CourseExercise>> NextExercise(const ArgParser& p,
                                                                    const client::Remote& remote) {
  if (!p.Flag("course")) return std::optional<client::CourseExercise>();
  auto next = client::NextCourseExercise(remote, p.Has("exercise") ? p.Int("exercise") : 0,
                                         remote.timeout_s);
  if (!next.ok()) return next.error();
  if (!next->may_attempt)
    return vsurg::Error{vsurg::ErrorCode::kResourceExhausted,
                        "today's attempts at '" + next->title + "' are used up", "course"};
  std::cerr << "vsurg-station: course '" << next->course << "', exercise " << next->position << ". "
            << next->title << " (" << next->scene << "): " << next->attempts << " attempts, "
            << next->streak << " of " << next->consecutive << " passes in a row; targets:";
  for (const std::string& t : next->targets) std::cerr << " " << t << ";";
  std::cerr << "\n";
  return std::optional<client::CourseExercise>(*next);
}

// The scene as the server will run it (the same file gives the same vertex order), with an
// exercise's task.
vsurg::Expected<sim::Scene> StationScene(const std::string& name,
                                         const std::optional<client::CourseExercise>& exercise) {
  auto scene = sim::LoadSceneByName(name);
  if (!scene.ok()) return vsurg::Error{scene.error().code, "scene: " + scene.error().message, ""};
  if (!exercise) return scene;
  if (!exercise->task.empty()) {
    auto task = vsurg::scoring::ApplyTaskSettings(scene->task, exercise->task);
    if (!task.ok())
      return vsurg::Error{task.error().code, "exercise task: " + task.error().message, ""};
    scene->task = *task;
  }
  const vsurg::scoring::TaskSpec& t = scene->task;
  const vsurg::scoring::TaskDisplayUnit unit = vsurg::scoring::DisplayUnitOf(t.kind);
  const std::string u = std::string(" ") + unit.name;
  std::cerr << "vsurg-station: task: "
            << (t.kind == vsurg::scoring::TaskKind::kTwist ? "twist to " : "press to ")
            << Fixed(t.target * unit.per_si, 1) << u << " within "
            << Fixed(t.tolerance * unit.per_si, 1) << u << ", held " << Fixed(t.hold_s, 1)
            << " s, under " << Fixed(t.force_limit, 1) << " N, in " << Fixed(t.time_limit, 0)
            << " s\n";
  return scene;
}

vsurg::Expected<client::StationConfig> ConfigFor(
    const ArgParser& p, const std::string& scene_name, const sim::Scene& scene,
    const std::optional<client::CourseExercise>& exercise) {
  client::StationConfig config;
  config.scene = scene_name;
  if (exercise) config.exercise_id = exercise->exercise_id;
  if (p.Has("join")) config.join = static_cast<uint64_t>(p.Int("join"));
  if (p.Has("instruct")) {
    config.instruct = static_cast<uint64_t>(p.Int("instruct"));
    auto mode = sim::ParseGuideMode(p.String("mode"));
    if (!mode.ok() || *mode == sim::GuideMode::kNone)
      return vsurg::InvalidArgument("--mode", "observe or guide");
    config.guide = {*mode, *mode == sim::GuideMode::kGuide ? p.Double("alpha") : 0.0};
  }
  auto rendering = client::ParseLocalRendering(p.String("local-model"));
  if (!rendering.ok()) return rendering.error();
  auto passivity = client::ParsePassivityMode(p.String("passivity"));
  if (!passivity.ok()) return passivity.error();
  config.rate_hz = p.Double("rate");
  config.rendering = *rendering;
  config.passivity = *passivity;
  config.deadband = p.Double("deadband");
  config.force_limit_n = scene.task.force_limit;
  config.model_hold_s = p.Double("model-hold");
  if (p.Has("force-log")) config.force_log = p.String("force-log");
  config.reconnect = !p.Flag("no-reconnect");
  config.realtime_priority = p.Int("realtime-priority");
  return config;
}

// What a trial is drawn with: the window or offscreen surface, the tissue's view and its
// quality governor, the rest surface for the press depth.
struct Screen {
  std::unique_ptr<client::GlSurface> gl;
  std::unique_ptr<client::MeshView> view;
  std::optional<client::Quality> fixed_quality;  // --quality other than auto
  std::unique_ptr<client::QualityGovernor> governor;
  const vsurg::geometry::TriMesh* rest = nullptr;
  std::unique_ptr<vsurg::geometry::Bvh> rest_bvh;
  // A coil limb's twist frames remade into the surface (the scene's own deformer), or none.
  std::optional<client::CoilTwistView> twist;
  std::vector<int32_t> twist_indices;
  std::vector<vsurg::geometry::Vec3> twist_positions;
};

// The frame loop's state: what the trial showed so far and when it is over.
struct Trial {
  Trial(const ArgParser& options, const sim::Scene& trained, Screen& drawn, client::Station& st,
        std::function<bool()> finished)
      : p(options), scene(trained), screen(drawn), station(st), played_out(std::move(finished)) {}
  const ArgParser& p;
  const sim::Scene& scene;
  Screen& screen;
  client::Station& station;
  std::function<bool()> played_out;  // a replay or virtual hand finished
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  double live_now = 0;  // seconds live, summed over sessions
  double last_tick = 0;
  bool was_live = false;  // at the last tick
  bool screenshot_taken = false, ended_by_replay = false;
  double replay_done_at = -1;
  uint64_t generation = 0, last_sent = 0;
  double rate_hz = 0, last_rate_at = 0;
  client::StationStats hud_stats;  // the HUD's figures, refreshed twice a second
  client::StationView shown;
  client::StationView shown_second;      // two hands: the second device's, while its channel runs
  client::StationStats second_stats;     // two hands: the second channel's, read at the end
  double held_s = 0, last_frame_at = 0;  // the task's quantity within tolerance, so far
  double confirmed_at = -1;              // a needle's confirmation, live time
  std::vector<double> draw_ms;           // per frame: draw and finish, ms
  std::array<std::vector<double>, 3> probe_ms;  // --quality auto: the frames before the trial, ms
  client::Quality started_at = client::Quality::kHigh;  // the level the trial started at
  // An instructor's station: the mode's switches (scripted and from the keys).
  std::optional<client::InstructorControls> controls;

  // The channel's news (a new session's rest, the moved vertices, the latest view) and the
  // overlay drawn over it this frame.
  client::Overlay Compose(const client::StationStatus& st, double tick) {
    client::Overlay overlay;
    uint64_t channel_generation = 0, channel_session = 0;
    std::vector<vsurg::wire::SceneChunk> chunks;
    const bool refresh_hud = tick - last_rate_at >= 0.5;
    const bool has_channel =
        station.WithChannel([&](client::StationChannel& channel, const client::StationStatus& at) {
          channel_generation = at.generation;
          channel_session = at.session;
          chunks = channel.TakeSceneChunks();
          channel.TakeView(shown);
          if (refresh_hud) hud_stats = channel.stats();
        });
    if (!has_channel) {
      overlay.hud = {"vsurg station  " + scene.name,
                     std::string(client::StationStateName(st.state)) + " ...",
                     st.last_error.substr(0, 60)};
      return overlay;
    }
    if (channel_generation != generation) {
      generation = channel_generation;
      screen.view->ResetToRest();  // a new session starts from the tissue at rest
    }
    for (const auto& chunk : chunks) {
      if (chunk.topology) {
        screen.view->ApplyFaces(chunk.face_indices, chunk.faces);
      } else if (!chunk.twist) {
        screen.view->Apply(chunk.indices, chunk.positions);
      } else if (screen.twist &&
                 screen.twist->Shape(*chunk.twist, screen.twist_indices, screen.twist_positions)) {
        screen.view->Apply(screen.twist_indices, screen.twist_positions);
      }
    }
    if (refresh_hud) {
      // A new session's channel counts from zero again.
      rate_hz = last_rate_at > 0 && hud_stats.sent >= last_sent
                    ? static_cast<double>(hud_stats.sent - last_sent) / (tick - last_rate_at)
                    : 0;
      last_sent = hud_stats.sent;
      last_rate_at = tick;
    }
    Gauges(overlay, tick);
    Hud(overlay, channel_session);
    SecondHand(overlay);
    return overlay;
  }

  // Two hands: the second device's instrument where it is, while its channel runs.
  void SecondHand(client::Overlay& overlay) {
    overlay.show_second = station.WithSecondChannel(
        [&](client::StationChannel& second) { second.TakeView(shown_second); });
    overlay.second_tip = shown_second.sample.position;
    overlay.second_orientation = shown_second.sample.orientation;
    overlay.second_grasping = shown_second.command.grasping;
    if (scene.cut && scene.cut->grasper)
      overlay.guidance.grasp = overlay.show_second ? (overlay.second_grasping ? 1 : 0) : -1;
  }

  // The task's gauges, and how long the task's quantity has been held within tolerance.
  void Gauges(client::Overlay& overlay, double tick) {
    overlay.guidance = Guidance(scene, shown, hud_stats, live_now);
    client::Guidance& g = overlay.guidance;
    if (!g.twist && !g.palpate && !g.needle && !g.cut)
      g.current = PressDepth(*screen.rest_bvh, *screen.rest, shown);
    const bool within =
        std::abs(std::abs(g.current) - g.target) <= g.tolerance && g.force_n <= g.force_limit_n;
    held_s = within ? held_s + (tick - last_frame_at) : 0;
    g.held_s = held_s;
  }

  // The stylus and the HUD's lines.
  void Hud(client::Overlay& overlay, uint64_t session) const {
    const client::StationStats& s = hud_stats;
    overlay.show_stylus = true;
    overlay.tip = shown.sample.position;
    overlay.orientation = shown.sample.orientation;
    overlay.force = shown.force;
    overlay.contact = shown.command.contact;
    overlay.grasping = shown.command.grasping;
    const bool palpate = scene.task.kind == vsurg::scoring::TaskKind::kPalpate;
    const bool needle = scene.task.kind == vsurg::scoring::TaskKind::kInsert;
    overlay.hud = {"vsurg station  " + scene.name + "  session " + std::to_string(session) +
                       "  view " + client::QualityName(screen.view->quality()) +
                       (screen.fixed_quality ? "" : " (auto)"),
                   sim::LinkStatus(rate_hz, s.rtt_p50_us, s.loss),
                   needle ? "needle depth " + Fixed(overlay.guidance.current * 1e3, 1) +
                                " mm   force " + Fixed(shown.force.norm(), 2) + " N"
                   : palpate ? "force " + Fixed(shown.force.norm(), 2) + " N   lumps marked " +
                                   std::to_string(s.marks)
                   : overlay.guidance.cut
                       ? "blade force " + Fixed(shown.force.norm(), 2) + " N   off the line " +
                             Fixed(overlay.guidance.current * 1e3, 1) + " mm"
                       : "twist " + Fixed(shown.command.twist * 180 / M_PI, 1) + " deg   force " +
                             Fixed(shown.force.norm(), 2) + " N",
                   // A palpation's score tells whether the marks found the lumps, a needle's
                   // whether the tip is where it should be: at the end.
                   palpate  ? std::string("search the tissue; the score comes at the end")
                   : needle ? std::string("place the needle; the score comes at the end")
                            : "score " + Fixed(shown.command.score, 1) + " / 10"};
    // The trainee sees an instructor in the session, and how (the answers carry the mode and α).
    if (!controls && shown.command.guide_mode != 0)
      overlay.hud.push_back(shown.command.guide_mode == 1
                                ? std::string("four hands: an instructor is observing")
                                : "four hands: guided, instructor's share " +
                                      Fixed(shown.command.guide_alpha, 2));
    if (controls) {
      const sim::GuideRequest g = station.guide();
      overlay.hud.push_back(
          std::string("instructing: ") + sim::GuideModeName(g.mode) +
          (g.mode == sim::GuideMode::kGuide ? " at alpha " + Fixed(g.alpha, 2) : "") +
          "   next alpha " + Fixed(controls->alpha(), 1) + "   " +
          std::string(client::InstructorControls::kHelp));
      if (const std::string why = station.guide_error(); !why.empty())
        overlay.hud.push_back(why.substr(0, 80));
    }
    // Beyond what the local model holds faithfully (docs/BENCHMARKS.md "Haptics across
    // networks": within 20% of the no-delay force up to 300 ms round trips, 1% loss), the
    // trainee is told plainly instead of feeling a mushy tissue.
    if (s.rtt_p50_us > 300e3 || s.loss > 0.10)
      overlay.hud.push_back("LINK TOO POOR FOR FAITHFUL TOUCH: " + Fixed(s.rtt_p50_us / 1e3, 0) +
                            " ms round trip, " + Fixed(100 * s.loss, 0) +
                            "% lost (limits 300 ms, 10%)");
  }

  // The frame drawn and finished: its whole cost in ms, not just the commands queued.
  double DrawFinished(const client::Overlay& overlay) {
    client::GlSurface& gl = *screen.gl;
    const auto draw_start = std::chrono::steady_clock::now();
    screen.view->Draw(gl.width(), gl.height(), overlay);
    gl.Finish();
    return 1e3 * Seconds(draw_start);
  }

  // A trial's frame, its time kept; the quality follows the measured times unless fixed.
  void Draw(const client::Overlay& overlay) {
    draw_ms.push_back(DrawFinished(overlay));
    if (!screen.fixed_quality) screen.view->SetQuality(screen.governor->Update(draw_ms.back()));
  }

  // The first frame, drawn before the session is joined: the renderer's one-off costs (a software
  // renderer compiles its shaders at its first draw, seconds on a busy machine) are paid before
  // the trial's clock runs, and --screenshot-before is the tissue at rest before any input. Not
  // counted in the frame times, nor shown to the quality governor.
  vsurg::Status FirstFrame() {
    client::GlSurface& gl = *screen.gl;
    const client::Overlay overlay = Compose(station.status(), 0);
    DrawFinished(overlay);
    if (p.Has("screenshot-before"))
      if (auto s = gl.SaveScreenshot(p.String("screenshot-before")); !s.ok()) return s;
    gl.EndFrame();
    started_at = screen.fixed_quality ? *screen.fixed_quality : ChooseQuality(overlay);
    started = std::chrono::steady_clock::now();  // --connect-timeout counts from the join
    return vsurg::Status::Ok();
  }

  // --quality auto, before the trial: kProbeFrames frames of the tissue at rest at high, then at
  // medium if high was too slow (each level's first frame uncounted: it compiles that level's
  // shaders). The trial starts at the level client::StartingQuality picks, and the governor never
  // takes it higher: no slow frames in the trial while it decides.
  client::Quality ChooseQuality(const client::Overlay& overlay) {
    constexpr int kProbeFrames = 12;
    const double budget_ms = 1e3 / p.Double("fps");
    for (client::Quality q : {client::Quality::kHigh, client::Quality::kMedium}) {
      screen.view->SetQuality(q);
      for (int i = 0; i <= kProbeFrames; ++i) {
        const double ms = DrawFinished(overlay);
        if (i > 0) probe_ms[static_cast<size_t>(q)].push_back(ms);
        screen.gl->EndFrame();
      }
      if (client::StartingQuality(probe_ms, budget_ms) == q) break;
    }
    const client::Quality chosen = client::StartingQuality(probe_ms, budget_ms);
    screen.governor = std::make_unique<client::QualityGovernor>(chosen, budget_ms, chosen);
    screen.view->SetQuality(chosen);
    return chosen;
  }

  // --screenshot at --screenshot-at.
  vsurg::Status Screenshots(bool live) {
    client::GlSurface& gl = *screen.gl;
    const bool at_time = p.Has("screenshot-at") && live && live_now >= p.Double("screenshot-at");
    if (p.Has("screenshot") && !screenshot_taken && at_time) {
      screenshot_taken = true;
      if (auto s = gl.SaveScreenshot(p.String("screenshot")); !s.ok()) return s;
    }
    return vsurg::Status::Ok();
  }

  // When to stop: the replay played out (and settled), the time is up, the window closed, or a
  // signal.
  bool Done(bool live) {
    if (live && played_out() && replay_done_at < 0) replay_done_at = live_now;
    const double duration = p.Double("duration");
    if (g_interrupted || screen.gl->ShouldClose() || screen.gl->Input().finish) return true;
    // A palpation's search ends at its time limit (the trainee may end it sooner: Enter); so
    // does a needle insertion, which also ends a second after its tip was confirmed in place.
    const bool searches = scene.task.kind == vsurg::scoring::TaskKind::kPalpate ||
                          scene.task.kind == vsurg::scoring::TaskKind::kInsert;
    if (live && searches && live_now >= scene.task.time_limit) return true;
    if (live && scene.task.kind == vsurg::scoring::TaskKind::kInsert && hud_stats.marks > 0) {
      if (confirmed_at < 0) confirmed_at = live_now;
      if (live_now - confirmed_at >= 1.0) return ended_by_replay = true;
    }
    if (duration > 0 && live && live_now >= duration) return true;
    if (duration <= 0 && replay_done_at >= 0 && live_now - replay_done_at >= p.Double("settle"))
      return ended_by_replay = true;
    return false;
  }

  // Frames at --fps until the trial is over; the last frame is kept for --screenshot without
  // --screenshot-at. An error ends the station.
  vsurg::Status Run() {
    const auto frame = std::chrono::duration<double>(1.0 / p.Double("fps"));
    auto next_frame = std::chrono::steady_clock::now();
    for (;;) {
      const client::StationStatus st = station.status();
      if (st.state == client::StationState::kFailed)
        return vsurg::Error{vsurg::ErrorCode::kUnavailable, st.last_error, ""};
      if (st.generation == 0 && Seconds(started) > p.Double("connect-timeout"))
        return vsurg::Error{vsurg::ErrorCode::kUnavailable,
                            "no session within --connect-timeout: " + st.last_error, ""};
      const bool live = st.state == client::StationState::kLive;
      const double tick = Seconds(started);
      if (live && was_live) live_now += tick - last_tick;  // between two live ticks only
      last_tick = tick;
      was_live = live;
      if (controls && live)
        if (auto asked = controls->Next(live_now, screen.gl->Input())) station.RequestGuide(*asked);
      const client::Overlay overlay = Compose(st, tick);
      last_frame_at = tick;
      Draw(overlay);
      if (vsurg::Status s = Screenshots(live); !s.ok()) return s;
      if (Done(live)) {
        if (p.Has("screenshot") && !screenshot_taken)
          if (auto s = screen.gl->SaveScreenshot(p.String("screenshot")); !s.ok()) return s;
        screen.gl->EndFrame();
        return vsurg::Status::Ok();
      }
      screen.gl->EndFrame();
      next_frame += std::chrono::duration_cast<std::chrono::steady_clock::duration>(frame);
      const auto now = std::chrono::steady_clock::now();
      if (now > next_frame) next_frame = now;
      std::this_thread::sleep_until(next_frame);
    }
  }
};

// The surface (a window, or offscreen) and the tissue's view on it.
vsurg::Expected<Screen> OpenScreen(const ArgParser& p, const sim::Scene& scene,
                                   const sim::SceneMesh& mesh, sim::VisualModel visual) {
  Screen screen;
  const std::string quality = p.String("quality");
  for (client::Quality q :
       {client::Quality::kLow, client::Quality::kMedium, client::Quality::kHigh})
    if (quality == client::QualityName(q)) screen.fixed_quality = q;
  if (!screen.fixed_quality && quality != "auto")
    return vsurg::InvalidArgument("--quality", "auto, low, medium or high");
  auto surface = p.Flag("headless")
                     ? client::GlSurface::CreateHeadless(p.Int("width"), p.Int("height"))
                     : client::GlSurface::CreateWindow("vsurg station: " + scene.name,
                                                       p.Int("width"), p.Int("height"));
  if (!surface.ok()) return surface.error();
  screen.gl = std::move(surface).value();
  screen.view = std::make_unique<client::MeshView>(mesh.surface, std::move(visual));
  screen.governor = std::make_unique<client::QualityGovernor>(
      screen.fixed_quality.value_or(client::Quality::kHigh), 1e3 / p.Double("fps"));
  screen.view->SetQuality(screen.governor->level());
  screen.rest = &mesh.surface;
  screen.twist = client::CoilTwistView::For(scene, mesh);
  screen.rest_bvh = std::make_unique<vsurg::geometry::Bvh>(mesh.surface);
  return screen;
}

// A search's outcome drawn on the tissue (the lumps it hid, the marks made), the panel below it.
// A mark is where the tool pressed the surface in, often millimetres under its rest: its pin
// stands where the rest surface is above it (the first face up the view's vertical, else the
// nearest), so that it shows on the tissue the summary draws at rest.
void ShowFindings(const vsurg::scoring::PalpationOutcome& outcome, const Screen& screen,
                  client::Overlay& last) {
  for (size_t i = 0; i < outcome.lumps.size(); ++i) {
    const vsurg::scoring::Lump& l = outcome.lumps[i];
    last.findings.rings.push_back(
        {l.surface, l.centre, l.radius, i < outcome.found.size() && outcome.found[i]});
  }
  const Eigen::Vector3d up = screen.view->visual().up.normalized();
  const auto& rest = screen.rest->positions;
  for (const auto& m : outcome.marks) {
    Eigen::Vector3d at = m.position;
    if (const auto hit = screen.rest_bvh->FirstHit(rest, at, at + 0.1 * up); hit.triangle >= 0)
      at = hit.point;
    else if (const auto near = screen.rest_bvh->Closest(rest, at); near.triangle >= 0)
      at = near.point;
    last.findings.pins.push_back({at, m.lump});
  }
  last.summary.low = true;
  last.summary.lines.push_back(outcome.lumps.empty()
                                   ? "No lump was hidden in this pad"
                                   : "Rings: where the lumps were (green found, red missed)");
  if (!outcome.marks.empty())
    last.summary.lines.push_back("Pins: your marks (orange: no lump there)");
}

// The end-of-trial summary on screen: the score and what lowered it (a window keeps it until
// closed, or 15 s). A panel's size settles over its first frames (ImGui fits it to its text):
// the screenshot is of the third.
vsurg::Status ShowSummary(const ArgParser& p, const sim::Scene& scene, Screen& screen,
                          const client::SessionSummary& summary) {
  client::GlSurface& gl = *screen.gl;
  if (!summary.has_metrics || !(p.Has("screenshot-summary") || !gl.headless()))
    return vsurg::Status::Ok();
  client::Overlay last;
  last.hud = {"vsurg station  " + scene.name + "  session " + std::to_string(summary.id)};
  last.summary.show = true;
  last.summary.score = summary.metrics.score;
  last.summary.lines = vsurg::scoring::ExplainScore(summary.metrics, scene.task);
  if (last.summary.lines.empty()) last.summary.lines = {"Nothing lowered it: expert level"};
  for (const TargetLine& line : TargetLines(summary)) last.summary.lines.push_back(line.text);
  if (summary.palpation) ShowFindings(*summary.palpation, screen, last);
  const auto shown_at = std::chrono::steady_clock::now();
  for (int frames = 1;; ++frames) {
    screen.view->Draw(gl.width(), gl.height(), last);
    if (frames == 3 && p.Has("screenshot-summary"))
      if (auto s = gl.SaveScreenshot(p.String("screenshot-summary")); !s.ok()) return s;
    gl.EndFrame();
    if (gl.headless() ? frames >= 3 : gl.ShouldClose() || g_interrupted || Seconds(shown_at) > 15)
      return vsurg::Status::Ok();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// --quality auto's probe: each probed level's 90th percentile (ms); levels not probed are absent.
nlohmann::json ProbeJson(const std::array<std::vector<double>, 3>& probe_ms) {
  nlohmann::json j = nlohmann::json::object();
  for (client::Quality q : {client::Quality::kHigh, client::Quality::kMedium}) {
    const std::vector<double>& t = probe_ms[static_cast<size_t>(q)];
    if (!t.empty()) j[client::QualityName(q)] = Percentile(t, 0.9);
  }
  return j;
}

// The trial's figures as one JSON object (--json).
nlohmann::json SummaryJson(const client::SessionSummary& summary, const client::StationStatus& st,
                           const client::StationStats& stats, const Trial& trial,
                           int render_threads,
                           const std::optional<client::CourseExercise>& exercise) {
  nlohmann::json j = {
      {"session", summary.id},
      {"state", SessionStateName(summary.state)},
      {"end_reason", summary.end_reason},
      {"reconnects", st.reconnects},
      {"drops", st.drops},
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
      {"scene_bytes", stats.scene_bytes},
      {"topology_bytes", stats.topology_bytes},
      {"max_force_n", stats.max_force},
      {"loop_hz", stats.loop_hz},
      {"loop_hz_min_1s", stats.loop_hz_min},
      {"loop_hz_max_1s", stats.loop_hz_max},
      {"frames", trial.draw_ms.size()},
      {"quality_start", client::QualityName(trial.started_at)},
      {"quality_end", client::QualityName(trial.screen.view->quality())},
      {"quality_probe_p90_ms", ProbeJson(trial.probe_ms)},
      {"draw_ms_p50", Percentile(trial.draw_ms, 0.5)},
      {"render_threads", render_threads},
      {"draw_ms_p99", Percentile(trial.draw_ms, 0.99)},
      {"second_hand",
       {{"received", trial.second_stats.received}, {"max_force_n", trial.second_stats.max_force}}},
      {"metrics_recorded", summary.has_metrics},
      {"metrics", vsurg::scoring::TrialMetricsToJson(summary.metrics)}};
  if (exercise) {
    nlohmann::json targets = nlohmann::json::array();
    for (const auto& t : summary.targets)
      targets.push_back(
          {{"metric", t.metric}, {"value", t.value}, {"target", t.target}, {"met", t.met}});
    j["exercise"] = {{"id", exercise->exercise_id},
                     {"title", exercise->title},
                     {"targets", targets},
                     {"passed", summary.targets_passed}};
  }
  return j;
}

void PrintSummary(const client::SessionSummary& summary, const client::StationStatus& st,
                  const client::StationStats& stats) {
  const auto& m = summary.metrics;
  std::cout << "session " << summary.id << " " << SessionStateName(summary.state) << " ("
            << summary.end_reason << "): score " << Fixed(m.score, 1) << "/10, completed "
            << (m.completed ? "yes" : "no") << ", peak force " << Fixed(m.peak_force, 2) << " N, "
            << stats.received << "/" << stats.sent << " datagrams answered, RTT p50 "
            << Fixed(stats.rtt_p50_us, 0) << " us, " << st.reconnects << " reconnects\n";
  for (const TargetLine& line : TargetLines(summary)) std::cout << "  " << line.text << "\n";
}

int Run(const std::vector<std::string>& args) {
  ArgParser p("vsurg-station",
              "A trainee's station: joins a session on the server, streams the stylus over UDP "
              "at 1 kHz and draws the tissue (window, or --headless offscreen).");
  DeclareOptions(p);
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  if (auto rc = CheckOptions(p)) return *rc;
  // On a software renderer the frame shares the cores with the haptic threads (and, on this
  // machine kind, the server): twice as many rasterizer threads as cores kept the frame's p99
  // lower with the server beside it (docs/BENCHMARKS.md, "Rasterizer threads"). First, while this
  // is the only thread: it sets an environment variable.
  const int render_threads = client::RequestSoftwareRenderThreads(
      p.Int("render-threads") >= 0
          ? p.Int("render-threads")
          : static_cast<int>(std::clamp(2 * std::thread::hardware_concurrency(), 2u, 32u)));
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return vsurg::cli::UsageError(std::cerr, p.command(), remote.error());
  auto exercise = NextExercise(p, *remote);
  if (!exercise.ok()) return Fail(exercise.error().message);
  const std::string scene_name = *exercise ? (*exercise)->scene : p.String("scene");
  auto scene = StationScene(scene_name, *exercise);
  if (!scene.ok()) return Fail(scene.error().message);
  auto mesh = sim::BuildSceneMesh(scene->mesh);
  if (!mesh.ok()) return Fail("scene mesh: " + mesh.error().message);
  auto visual = sim::BuildVisualModel(*scene, mesh->surface);
  if (!visual.ok()) return Fail("scene visual model: " + visual.error().message);
  auto config = ConfigFor(p, scene_name, *scene, *exercise);
  if (!config.ok()) return vsurg::cli::UsageError(std::cerr, p.command(), config.error());

  // The device first (bad options are reported before any window opens); the keyboard and
  // mouse need the window, so that one is opened after it.
  client::DeviceRequest request = DeviceRequestFor(p, *scene, *mesh);
  const bool needs_window = request.kind == "keyboard-mouse";
  vsurg::Expected<std::unique_ptr<client::HapticDevice>> device =
      needs_window ? vsurg::Expected<std::unique_ptr<client::HapticDevice>>(nullptr)
                   : client::OpenDevice(request);
  if (!device.ok()) return Usage("", device.error().field + ": " + device.error().message);
  auto screen = OpenScreen(p, *scene, *mesh, std::move(*visual));
  if (!screen.ok()) {
    if (screen.error().code == vsurg::ErrorCode::kInvalidArgument)
      return vsurg::cli::UsageError(std::cerr, p.command(), screen.error());
    return Fail(screen.error().message);
  }
  if (needs_window) {
    request.window_input = [gl = screen->gl.get()] { return gl->Input(); };
    device = client::OpenDevice(request);
    if (!device.ok()) return Fail(device.error().message);
  }
  // Two hands: the second device, for a scene with a second tool.
  std::unique_ptr<client::HapticDevice> second;
  if (p.Has("second-device")) {
    if (!scene->cut || !scene->cut->grasper)
      return Usage("second-device", "scene '" + scene_name + "' has no second tool");
    auto opened = client::OpenSecondDevice(p, *scene, request);
    if (!opened.ok()) return Usage("second-device", opened.error().message);
    second = std::move(*opened);
  }
  auto* replay = dynamic_cast<client::ReplayDevice*>(device->get());
  auto* hand = dynamic_cast<client::VirtualHandDevice*>(device->get());
  auto* searcher = dynamic_cast<client::SearchingHandDevice*>(device->get());
  config->twist_shape_key = screen->twist ? screen->twist->key() : 0;
  client::Station station(*remote, device->get(), *config);
  if (second) station.SetSecondDevice(second.get());

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  Trial trial{p, *scene, *screen, station, [&] {
                return (replay && replay->finished()) || (hand && hand->finished()) ||
                       (searcher && searcher->finished());
              }};
  if (vsurg::Status s = trial.FirstFrame(); !s.ok()) return Fail(s.error().message);
  // The session's life on its own thread: a frame that takes seconds (a driver's stall) does not
  // delay noticing a lost server.
  station.StartSupervisor([](const client::StationStatus& st) {
    vsurg::LogFields fields{{"state", client::StationStateName(st.state)}, {"session", st.session}};
    if (!st.last_error.empty()) fields.emplace_back("reason", st.last_error);
    vsurg::LogEvent("vsurg-station", "state", fields);
  });
  if (config->instruct != 0)
    trial.controls.emplace(*client::ParseGuidePlan(p.String("guide-plan")), p.Double("alpha"));
  if (vsurg::Status s = trial.Run(); !s.ok()) return Fail(s.error().message);

  const client::StationStatus st = station.status();
  const client::StationStats stats = station.total_stats();
  trial.second_stats = station.second_hand_stats();
  auto summary = station.Finish(trial.ended_by_replay ? "completed"
                                : g_interrupted       ? "interrupted"
                                                      : "stopped");
  if (!summary.ok()) return Fail(summary.error().message);
  if (vsurg::Status s = ShowSummary(p, *scene, *screen, *summary); !s.ok())
    return Fail(s.error().message);
  if (p.Flag("json"))
    std::cout << SummaryJson(*summary, st, stats, trial, render_threads, *exercise).dump() << "\n";
  else
    PrintSummary(*summary, st, stats);
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
