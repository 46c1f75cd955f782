// vsurg-monitor: for instructors. `list` shows the live sessions; `follow` streams one session's
// telemetry (MonitorService.Watch, 30 Hz) and shows it as plain text lines for terminals
// (--text), or draws the trainee's tissue as the server has deformed it in an OpenGL window (or
// offscreen with --headless --screenshot). Needs an instructor's or an administrator's token.
//
// Exit codes: 0 done (the session ended, or --duration passed), 1 refused or the server failed,
// 2 usage.
#include <grpcpp/grpcpp.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <thread>
#include <variant>

#include "client/net/remote.h"
#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "common/core/args.h"
#include "common/core/format.h"
#include "common/sim/scene.h"
#include "common/sim/telemetry.h"
#include "common/sim/visual_model.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace {

namespace v1 = vsurg::v1;
namespace client = vsurg::client;
namespace convert = vsurg::convert;
namespace sim = vsurg::sim;
using vsurg::Expected;
using vsurg::Fixed;
using vsurg::Status;
using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;

std::atomic<bool> g_interrupted{false};
void OnSignal(int) {
  g_interrupted = true;
}

int Usage(const ArgParser& p, const vsurg::Error& e) {
  return vsurg::cli::UsageError(std::cerr, p.command(), e);
}

int List(const std::vector<std::string>& args) {
  ArgParser p("vsurg-monitor list", "Lists the live sessions (created, running, stalled).");
  client::AddRemoteOptions(p);
  p.Option("all", Kind::kFlag, "also the ended ones, with their scores");
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return Usage(p, remote.error());
  auto stub = v1::SessionService::NewStub(remote->channel);
  grpc::ClientContext ctx;
  remote->Prepare(ctx);
  v1::ListSessionsRequest req;
  req.set_live_only(!p.Flag("all"));
  v1::ListSessionsResponse resp;
  const grpc::Status s = stub->List(&ctx, req, &resp);
  if (!s.ok()) return client::ReportRpcError(std::cerr, p.command(), s);
  std::cout << "id\ttrainee\tscene\tstate\tscore\n";
  for (const v1::Session& session : resp.sessions())
    std::cout << session.id() << "\t" << session.trainee() << "\t" << session.scene() << "\t"
              << convert::StateName(session.state()) << "\t"
              << (session.has_metrics() ? Fixed(session.metrics().score(), 1) : "-") << "\n";
  return 0;
}

// The sample's fields as the dashboard names them (sim::TelemetryFields), after the monitor's
// own clock, the session and its state.
std::string TextLine(const v1::Telemetry& t, double since_s) {
  return "watch_s=" + Fixed(since_s, 1) + " session=" + std::to_string(t.session_id()) +
         " state=" + convert::StateName(t.state()) + " " +
         sim::TelemetryText(convert::FromProto(t));
}

// The Watch stream on its own thread; the main thread takes the newest message (latest wins).
class Follower {
 public:
  Follower(const client::Remote& remote, uint64_t session) {
    stub_ = v1::MonitorService::NewStub(remote.channel);
    context_.AddMetadata("authorization", "Bearer " + remote.token);
    v1::WatchRequest req;
    req.set_session_id(session);
    thread_ = std::thread([this, req] {
      auto reader = stub_->Watch(&context_, req);
      v1::Telemetry t;
      while (reader->Read(&t)) {
        std::lock_guard lock(mutex_);
        if (t.has_surface()) surface_ = t.surface();
        latest_ = t;
        ++messages_;
      }
      const grpc::Status s = reader->Finish();
      std::lock_guard lock(mutex_);
      status_ = s;
    });
  }
  ~Follower() {
    context_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }
  // The newest telemetry since the last call, and the newest surface state if one came.
  bool Take(v1::Telemetry& out, std::optional<v1::SurfaceState>& surface) {
    std::lock_guard lock(mutex_);
    if (surface_) surface = std::move(surface_), surface_.reset();
    if (messages_ == taken_) return false;
    taken_ = messages_;
    out = latest_;
    return true;
  }
  std::optional<grpc::Status> finished() {
    std::lock_guard lock(mutex_);
    return status_;
  }
  uint64_t messages() {
    std::lock_guard lock(mutex_);
    return messages_;
  }

 private:
  std::unique_ptr<v1::MonitorService::Stub> stub_;
  grpc::ClientContext context_;
  std::mutex mutex_;
  v1::Telemetry latest_;
  std::optional<v1::SurfaceState> surface_;
  uint64_t messages_ = 0, taken_ = 0;
  std::optional<grpc::Status> status_;
  std::thread thread_;
};

// The first live session, waiting up to `wait_s` for one to appear.
std::optional<uint64_t> FirstLive(const client::Remote& remote, double wait_s, std::string& error) {
  auto stub = v1::SessionService::NewStub(remote.channel);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  do {
    grpc::ClientContext ctx;
    remote.Prepare(ctx);
    v1::ListSessionsRequest req;
    req.set_live_only(true);
    v1::ListSessionsResponse resp;
    const grpc::Status s = stub->List(&ctx, req, &resp);
    if (!s.ok()) {
      error = s.error_message() + " (gRPC " + std::to_string(int(s.error_code())) + ")";
      if (s.error_code() != grpc::StatusCode::UNAVAILABLE) return std::nullopt;
    } else {
      for (const v1::Session& session : resp.sessions())
        if (session.state() == v1::SESSION_STATE_RUNNING ||
            session.state() == v1::SESSION_STATE_STALLED)
          return session.id();
      error = "no live session";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  } while (std::chrono::steady_clock::now() < until && !g_interrupted);
  return std::nullopt;
}

void DeclareFollowOptions(ArgParser& p) {
  client::AddRemoteOptions(p);
  p.Option("session", Kind::kInt, "session id (default: the first running one)")
      .Option("wait", Kind::kDouble, "without --session: wait this long for one, s", false, "30")
      .Option("text", Kind::kFlag, "plain text lines, no OpenGL")
      .Option("print-hz", Kind::kDouble, "text lines per second", false, "2")
      .Within({0.01, 60})
      .Option("headless", Kind::kFlag, "render offscreen (EGL), no window")
      .Option("width", Kind::kInt, "image width, px", false, "960")
      .Option("height", Kind::kInt, "image height, px", false, "600")
      .Option("screenshot", Kind::kString, "PNG of the view when following ends")
      .Option("duration", Kind::kDouble, "stop after this many seconds (0: when the session ends)",
              false, "0");
}

// The session to follow: the one named, or the first live one within --wait. An exit code when
// there is none.
std::variant<uint64_t, int> SessionToFollow(const ArgParser& p, const client::Remote& remote) {
  if (p.Has("session")) {
    if (p.Int("session") <= 0) return std::cerr << p.command() << ": --session: must be > 0\n", 2;
    return static_cast<uint64_t>(p.Int("session"));
  }
  std::string error;
  auto first = FirstLive(remote, p.Double("wait"), error);
  if (!first) return std::cerr << p.command() << ": " << error << "\n", 1;
  return *first;
}

// The OpenGL side of following: the trainee's tissue as the telemetry and surface states say.
class FollowView {
 public:
  FollowView(std::unique_ptr<client::GlSurface> gl, uint64_t session)
      : gl_(std::move(gl)), session_(session) {}
  client::GlSurface& gl() { return *gl_; }

  // The scene's mesh and visual model, built again when the telemetry names another scene.
  Status UpdateScene(const std::string& scene_name) {
    if (scene_name == scene_name_) return Status::Ok();
    auto scene = sim::LoadSceneByName(scene_name);
    if (!scene.ok()) return scene.error();
    auto mesh = sim::BuildSceneMesh(scene->mesh);
    if (!mesh.ok()) return mesh.error();
    auto visual = sim::BuildVisualModel(*scene, mesh->surface);
    if (!visual.ok()) return visual.error();
    view_ = std::make_unique<client::MeshView>(mesh->surface, std::move(*visual));
    scene_name_ = scene_name;
    return Status::Ok();
  }

  // The moved vertices of a surface state, from the rest shape.
  void ApplySurface(const v1::SurfaceState& surface) {
    if (!view_) return;
    view_->ResetToRest();
    std::vector<int32_t> indices(surface.indices().begin(), surface.indices().end());
    std::vector<Eigen::Vector3f> positions;
    for (int k = 0; k + 2 < surface.positions_size(); k += 3)
      positions.emplace_back(surface.positions(k), surface.positions(k + 1),
                             surface.positions(k + 2));
    view_->Apply(indices, positions);
  }

  void Draw(const v1::Telemetry* latest) {
    if (view_) view_->Draw(gl_->width(), gl_->height(), OverlayOf(latest));
  }
  bool HasView() const { return view_ != nullptr; }

 private:
  client::Overlay OverlayOf(const v1::Telemetry* latest) const {
    client::Overlay overlay;
    const std::string title = "vsurg monitor  session " + std::to_string(session_);
    if (!latest) {
      overlay.hud = {title, "waiting ..."};
      return overlay;
    }
    overlay.show_stylus = true;
    overlay.tip = {latest->tip().x(), latest->tip().y(), latest->tip().z()};
    overlay.force = {latest->force().x(), latest->force().y(), latest->force().z()};
    overlay.contact = latest->contact();
    overlay.grasping = latest->grasping();
    overlay.hud = {
        title + "  " + latest->scene() + "  " + convert::StateName(latest->state()),
        "twist " + Fixed(latest->twist() * 180 / M_PI, 1) + " deg   torque " +
            Fixed(latest->torque(), 2) + " N·m",
        sim::LinkStatus(latest->haptic_rate_hz(), latest->rtt_us(), latest->packet_loss()),
        "score so far " + Fixed(latest->metrics().score(), 1) + " / 10"};
    return overlay;
  }

  std::unique_ptr<client::GlSurface> gl_;
  uint64_t session_;
  std::unique_ptr<client::MeshView> view_;
  std::string scene_name_;
};

// A window, an offscreen surface with --headless, or none with --text.
Expected<std::optional<FollowView>> OpenFollowView(const ArgParser& p, uint64_t session) {
  if (p.Flag("text")) return std::optional<FollowView>();
  auto surface =
      p.Flag("headless")
          ? client::GlSurface::CreateHeadless(p.Int("width"), p.Int("height"))
          : client::GlSurface::CreateWindow("vsurg monitor", p.Int("width"), p.Int("height"));
  if (!surface.ok()) return surface.error();
  return std::optional<FollowView>(std::in_place, std::move(*surface), session);
}

// How following ended: the screenshot asked for, the stream's refusal, or the last figures.
int FinishFollowing(const ArgParser& p, std::optional<FollowView>& view, Follower& follower,
                    uint64_t session, const v1::Telemetry* latest, bool ended, double seconds) {
  if (view && view->HasView() && p.Has("screenshot")) {
    if (auto s = view->gl().SaveScreenshot(p.String("screenshot")); !s.ok()) {
      std::cerr << p.command() << ": " << s.error().message << "\n";
      return 1;
    }
  }
  const auto finished = follower.finished();
  if (finished && !finished->ok()) {
    std::cerr << p.command() << ": refused or failed: " << finished->error_message() << " (gRPC "
              << static_cast<int>(finished->error_code()) << ")\n";
    return 1;
  }
  if (latest) {
    const auto& m = latest->metrics();
    std::cout << "session " << session << " " << (ended ? "ended" : "left") << ": "
              << follower.messages() << " telemetry messages; last: " << TextLine(*latest, seconds)
              << "; completed " << (m.completed() ? "yes" : "no") << ", peak force "
              << Fixed(m.peak_force_n(), 2) << " N\n";
  }
  return 0;
}

int Follow(const std::vector<std::string>& args) {
  ArgParser p("vsurg-monitor follow",
              "Follows one session live: text lines (--text), or the trainee's tissue in a window "
              "(or offscreen with --headless).");
  DeclareFollowOptions(p);
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return Usage(p, remote.error());
  if (p.Flag("text") && p.Has("screenshot"))
    return std::cerr << p.command() << ": --screenshot needs the OpenGL view (not --text)\n", 2;
  const auto chosen = SessionToFollow(p, *remote);
  if (const int* rc = std::get_if<int>(&chosen)) return *rc;
  const uint64_t session = std::get<uint64_t>(chosen);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  auto view = OpenFollowView(p, session);
  if (!view.ok()) return std::cerr << p.command() << ": " << view.error().message << "\n", 1;

  Follower follower(*remote, session);
  std::cout << "following session " << session << "\n" << std::flush;
  const auto started = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  const double print_hz = p.Double("print-hz"), duration = p.Double("duration");
  double next_print = 0;
  v1::Telemetry latest;
  bool have = false;
  for (;;) {
    std::optional<v1::SurfaceState> surface;
    if (follower.Take(latest, surface)) have = true;
    if (have && p.Flag("text") && seconds() >= next_print) {
      std::cout << TextLine(latest, seconds()) << "\n" << std::flush;
      next_print = seconds() + 1.0 / print_hz;
    }
    if (*view) {
      if (have) {
        if (Status s = (*view)->UpdateScene(latest.scene()); !s.ok())
          return std::cerr << p.command() << ": scene '" << latest.scene()
                           << "': " << s.error().message << "\n",
                 1;
      }
      if (surface) (*view)->ApplySurface(*surface);
      (*view)->Draw(have ? &latest : nullptr);
    }
    const bool ended = follower.finished().has_value();
    if (ended || g_interrupted || (*view && (*view)->gl().ShouldClose()) ||
        (duration > 0 && seconds() >= duration))
      return FinishFollowing(p, *view, follower, session, have ? &latest : nullptr, ended,
                             seconds());
    if (*view) (*view)->gl().EndFrame();
    std::this_thread::sleep_for(std::chrono::milliseconds(*view ? 16 : 20));
  }
}

const char* kHelp =
    "usage: vsurg-monitor <command> [options]\n\n"
    "commands:\n"
    "  list     the live sessions (--all: every session, with scores)\n"
    "  follow   follow one session live: --text for a terminal, else an OpenGL view\n\n"
    "Takes --server HOST:PORT and an instructor's or administrator's token (--token, "
    "--token-file, $VSURG_TOKEN).\n";

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::vector<std::string> all(argv + 1, argv + argc);
    if (all.empty()) return std::cerr << "vsurg-monitor: a command is required (see --help)\n", 2;
    const std::vector<std::string> rest(all.begin() + 1, all.end());
    if (all[0] == "--help" || all[0] == "-h" || all[0] == "help") return std::cout << kHelp, 0;
    if (all[0] == "list") return List(rest);
    if (all[0] == "follow") return Follow(rest);
    std::cerr << "vsurg-monitor: unknown command '" << all[0] << "' (see --help)\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "vsurg-monitor: fatal: " << e.what() << "\n";
    return 1;
  }
}
