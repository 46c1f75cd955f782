// The station's frame alone: one scene drawn headless (EGL surfaceless, Mesa llvmpipe here) at
// 1280×720 by each quality level, with the instrument and the HUD, while nothing else runs.
// "still": nothing moved since the last frame (the shadow pass and the mapping are skipped);
// "moving": the tissue moved every frame (the visual surface mapped and uploaded again, the
// shadow map drawn again); "/fine": low or medium drawing the fine visual surface instead of the
// coarse one (MeshView::SetCoarseBelowHigh), side by side in the same run. The station's figures
// with the server and the haptic threads beside it come from bench/station_view.sh.
//
//   build/bin/vsurg-microbench --benchmark_filter=StationFrame
#include <benchmark/benchmark.h>

#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "common/sim/scene.h"
#include "common/sim/visual_model.h"

namespace {

using vsurg::client::Quality;

// What moves between frames: nothing; the tissue (and so the shadow pass runs); the stylus over
// still tissue (the shadow pass runs for the tool's shadow, the tissue's depth copied back).
enum class Motion { kStill, kTissue, kTool };
const char* MotionName(Motion m) {
  return m == Motion::kStill ? "still" : m == Motion::kTissue ? "moving" : "tool";
}

void StationFrame(benchmark::State& state, const char* scene_name, Quality quality, Motion motion,
                  bool coarse) {
  auto surface = vsurg::client::GlSurface::CreateHeadless(1280, 720);
  auto scene = vsurg::sim::LoadSceneByName(scene_name);
  if (!surface.ok() || !scene.ok()) return state.SkipWithError("no headless OpenGL or scene");
  auto mesh = vsurg::sim::BuildSceneMesh(scene->mesh);
  auto visual = vsurg::sim::BuildVisualModel(*scene, mesh->surface);
  if (!mesh.ok() || !visual.ok()) return state.SkipWithError("scene mesh");
  vsurg::client::MeshView view(mesh->surface, std::move(*visual));
  view.SetQuality(quality);
  view.SetCoarseBelowHigh(coarse);
  vsurg::client::Overlay overlay;
  overlay.show_stylus = true;
  overlay.tip = 0.5 * (mesh->surface.positions.front() + mesh->surface.positions.back()) +
                Eigen::Vector3d(0.03, 0.03, 0.03);
  overlay.orientation = Eigen::Quaterniond::FromTwoVectors(
      Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1, 0.3, 0.4).normalized());
  overlay.guidance.show = true;
  overlay.guidance.target = scene->task.target;
  overlay.guidance.tolerance = scene->task.tolerance;
  overlay.guidance.force_limit_n = scene->task.force_limit;
  overlay.hud = {"vsurg station", "haptic 1000 Hz"};
  std::vector<int32_t> all(mesh->surface.positions.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int32_t>(i);
  std::vector<vsurg::geometry::Vec3> moved = mesh->surface.positions;
  for (int warm = 0; warm < 3; ++warm) view.Draw(1280, 720, overlay), (*surface)->Finish();
  double nudge = 0;
  for (auto _ : state) {
    if (motion == Motion::kTissue) {
      nudge = nudge > 0 ? 0 : 1e-4;  // the whole surface 0.1 mm up and back
      for (size_t i = 0; i < moved.size(); ++i)
        moved[i] = mesh->surface.positions[i] + Eigen::Vector3d(0, 0, nudge);
      view.Apply(all, moved);
    }
    if (motion == Motion::kTool) {
      nudge = nudge > 0 ? -1e-3 : 1e-3;  // the tip 1 mm sideways and back
      overlay.tip.x() += nudge;
    }
    view.Draw(1280, 720, overlay);
    (*surface)->Finish();
  }
  state.SetLabel(std::string(scene_name) + " " + vsurg::client::QualityName(quality) + " " +
                 MotionName(motion) + (coarse ? "" : " fine"));
}

void Register() {
  for (const char* scene : {"arm-torsion", "organ-surface-twist"})
    for (Quality q : {Quality::kLow, Quality::kMedium, Quality::kHigh})
      for (Motion motion : {Motion::kStill, Motion::kTissue, Motion::kTool})
        // Low and medium draw the coarse visual surface; "/fine" is the same level drawing the
        // fine one (high always draws the fine one). The stylus alone moving matters only where
        // there are shadows, on the surface each level draws by default.
        for (bool coarse : {true, false}) {
          if (!coarse && q == Quality::kHigh) continue;
          if (motion == Motion::kTool && (q == Quality::kLow || !coarse)) continue;
          benchmark::RegisterBenchmark(
              (std::string("StationFrame/") + scene + "/" + vsurg::client::QualityName(q) + "/" +
               MotionName(motion) + (coarse ? "" : "/fine"))
                  .c_str(),
              [=](benchmark::State& s) { StationFrame(s, scene, q, motion, coarse); })
              ->Unit(benchmark::kMillisecond)
              ->MinTime(1.0);
        }
}
const bool registered = (Register(), true);

}  // namespace
