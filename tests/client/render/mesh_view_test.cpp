// Headless rendering (EGL surfaceless, OpenGL 3.3 core on Mesa llvmpipe) of the station's view:
// a twist changes the image where the arm moved and nowhere else; the instrument appears where
// the stylus projects; its shadow darkens the tissue under it; a rigid turn of the physics limb
// turns the skin's pattern by the same angle; every scene draws without blank or black frames;
// each scene matches its stored reference image (tests/data/render/, rewritten with
// VSURG_UPDATE_RENDER_REFERENCES=1 when a change to the look is deliberate).
//
// VSURG_RENDER_OUT=DIR writes every image a test draws to DIR (to look at them).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "common/geometry/bvh.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/sim/visual_model.h"
#include "tests/support/thread_names.h"
#include "tests/support/wait.h"

namespace vsurg::client {
namespace {

constexpr int kWidth = 480, kHeight = 320;

void Keep(const RgbImage& image, const std::string& name) {
  if (const char* dir = std::getenv("VSURG_RENDER_OUT"))
    (void)WriteRgbPng(std::string(dir) + "/" + name + ".png", image.width, image.height, image.rgb);
}

// Pixels whose colour changed, and how many of them fall within `box` (x0, y0, x1, y1).
struct Diff {
  int changed = 0, inside = 0;
};

Diff Compare(const RgbImage& a, const RgbImage& b, Eigen::Vector4d box = Eigen::Vector4d::Zero(),
             int threshold = 30) {
  Diff d;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const size_t i = (static_cast<size_t>(y) * a.width + x) * 3;
      int delta = 0;
      for (int k = 0; k < 3; ++k) delta += std::abs(int(a.rgb[i + k]) - int(b.rgb[i + k]));
      if (delta > threshold) {
        ++d.changed;
        if (x >= box[0] && x <= box[2] && y >= box[1] && y <= box[3]) ++d.inside;
      }
    }
  return d;
}

// Mean absolute difference per channel (0–255) of two images of the same size.
double MeanDifference(const RgbImage& a, const RgbImage& b) {
  double sum = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) sum += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
  return a.rgb.empty() ? 0 : sum / a.rgb.size();
}

int DistinctColours(const RgbImage& image) {
  std::set<uint32_t> colours;
  for (size_t i = 0; i + 2 < image.rgb.size(); i += 3)
    colours.insert((uint32_t(image.rgb[i]) << 16) | (uint32_t(image.rgb[i + 1]) << 8) |
                   image.rgb[i + 2]);
  return static_cast<int>(colours.size());
}

// Mean luminance (0–255) over a square of half-size r around (x, y).
double Luminance(const RgbImage& image, Eigen::Vector2d at, int r) {
  double sum = 0;
  int n = 0;
  for (int y = static_cast<int>(at.y()) - r; y <= static_cast<int>(at.y()) + r; ++y)
    for (int x = static_cast<int>(at.x()) - r; x <= static_cast<int>(at.x()) + r; ++x) {
      if (x < 0 || y < 0 || x >= image.width || y >= image.height) continue;
      const size_t i = (static_cast<size_t>(y) * image.width + x) * 3;
      sum += 0.2126 * image.rgb[i] + 0.7152 * image.rgb[i + 1] + 0.0722 * image.rgb[i + 2];
      ++n;
    }
  return n ? sum / n : 0;
}

struct SceneView {
  sim::Scene scene;
  sim::SceneMesh mesh;
  std::unique_ptr<MeshView> view;
  explicit SceneView(const std::string& name) {
    auto s = sim::LoadSceneByName(name);
    EXPECT_TRUE(s.ok()) << name;
    scene = *s;
    auto m = sim::BuildSceneMesh(scene.mesh);
    EXPECT_TRUE(m.ok()) << name;
    mesh = std::move(*m);
    auto visual = sim::BuildVisualModel(scene, mesh.surface);
    EXPECT_TRUE(visual.ok()) << name;
    view = std::make_unique<MeshView>(mesh.surface, std::move(*visual));
  }
};

TEST(MeshViewTest, TwistedArmChangesTheImageAtTheWristOnly) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  auto scene = sim::LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  auto simulation = sim::Simulation::Create(*scene, {.threaded = false});
  ASSERT_TRUE(simulation.ok()) << simulation.error().message;
  auto trajectory = sim::ScriptedTrainee(*scene, sim::TraineeStyle::kGood);
  ASSERT_TRUE(trajectory.ok());
  auto visual = sim::BuildVisualModel(*scene, (*simulation)->rest_mesh());
  ASSERT_TRUE(visual.ok());

  MeshView view((*simulation)->rest_mesh(), std::move(*visual));
  view.Draw(kWidth, kHeight, {});
  const RgbImage rest = (*surface)->ReadPixels();
  Keep(rest, "arm-rest");
  ASSERT_EQ(rest.width, kWidth);
  ASSERT_EQ(rest.rgb.size(), size_t{kWidth} * kHeight * 3);
  EXPECT_GT(DistinctColours(rest), 500) << "shaded, textured skin expected";

  // Play the trainee up to the middle of the hold, where the twist is largest.
  std::vector<haptics::StylusSample> first_half(trajectory->begin(),
                                                trajectory->begin() + trajectory->size() / 2);
  double twist = 0;
  (*simulation)->Replay(first_half, [&](const auto&, const haptics::ForceCommand& c) {
    twist = std::max(twist, std::abs(c.twist));
  });
  ASSERT_GT(twist, 0.5) << "the scripted trainee should have twisted the arm";
  sim::VisualFrame frame;
  ASSERT_TRUE((*simulation)->TakeVisualFrame(frame));
  ASSERT_GT(frame.indices.size(), 10u);
  EXPECT_GT(view.Apply(frame.indices, frame.positions), 10);
  view.Draw(kWidth, kHeight, {});
  const RgbImage twisted = (*surface)->ReadPixels();
  Keep(twisted, "arm-twisted");

  // On screen, the box around the vertices the twist moved (and 6 px more for the shading of
  // their neighbours and the skin's relief), and the box around the held elbow end.
  const auto& rest_positions = (*simulation)->rest_mesh().positions;
  std::vector<bool> moved(rest_positions.size(), false);
  for (int32_t i : frame.indices) moved[i] = true;
  Eigen::Vector4d moved_box(1e9, 1e9, -1e9, -1e9), still_box = moved_box;
  double far_from_grasp = 0;
  for (size_t i = 0; i < rest_positions.size(); ++i) {
    const Eigen::Vector2d q = view.Project(rest_positions[i], kWidth, kHeight);
    Eigen::Vector4d& box = moved[i] ? moved_box : still_box;
    box = Eigen::Vector4d(std::min(box[0], q.x()), std::min(box[1], q.y()), std::max(box[2], q.x()),
                          std::max(box[3], q.y()));
    if (!moved[i]) far_from_grasp += 1;
  }
  ASSERT_GT(far_from_grasp, 10) << "the elbow end must stay put";
  moved_box += Eigen::Vector4d(-6, -6, 6, 6);
  const Diff diff = Compare(rest, twisted, moved_box);
  EXPECT_GT(diff.changed, 500) << "the twist must be visible";
  // Most of it where the arm moved (the rest is the twisted wrist's shadow on the table).
  EXPECT_GT(diff.inside, 0.75 * diff.changed);
  // The held end's pixels beyond the moved region do not change.
  Eigen::Vector4d held = still_box;
  if (moved_box[0] > still_box[0])
    held[2] = std::min(held[2], moved_box[0] - 1);
  else
    held[0] = std::max(held[0], moved_box[2] + 1);
  EXPECT_GT(held[2] - held[0], 20) << "some of the arm must be untouched on screen";
  EXPECT_EQ(Compare(rest, twisted, held).inside, 0);

  // Back to rest: the image is the rest image again (rendering is deterministic).
  view.ResetToRest();
  view.Draw(kWidth, kHeight, {});
  EXPECT_EQ(Compare(rest, (*surface)->ReadPixels()).changed, 0);
}

// A stylus pose above the sphere's top: the tip `height` above it, the shaft tilted toward the
// camera's right.
Overlay StylusAbove(const SceneView& s, double height) {
  Eigen::Vector3d top = Eigen::Vector3d::Constant(-1e9);
  for (const auto& p : s.mesh.surface.positions)
    if (p.z() > top.z()) top = p;
  Overlay o;
  o.show_stylus = true;
  o.tip = top + Eigen::Vector3d(0, 0, height);
  o.orientation = Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitX());
  return o;
}

TEST(MeshViewTest, TheInstrumentAppearsWhereTheStylusProjects) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  SceneView s("sphere-palpation-256");
  s.view->SetQuality(Quality::kLow);  // no shadows: every changed pixel is the tool's own
  s.view->Draw(kWidth, kHeight, {});
  const RgbImage plain = (*surface)->ReadPixels();
  Overlay o = StylusAbove(s, 0.01);
  s.view->Draw(kWidth, kHeight, o);
  const RgbImage with_tool = (*surface)->ReadPixels();
  Keep(with_tool, "probe");
  // The changed pixels lie along the projected shaft: their centroid near the projection of
  // the shaft's visible part, and the tip's own pixel changed.
  const Eigen::Vector3d shaft_axis = o.orientation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector2d tip = s.view->Project(o.tip + 0.002 * shaft_axis, kWidth, kHeight);
  EXPECT_GT(
      Compare(plain, with_tool, Eigen::Vector4d(tip.x() - 3, tip.y() - 3, tip.x() + 3, tip.y() + 3))
          .inside,
      10);
  // Everything the tool changed lies within a band around the projected shaft.
  int changed = 0, near_shaft = 0;
  const Eigen::Vector2d a = s.view->Project(o.tip, kWidth, kHeight);
  const Eigen::Vector2d b = s.view->Project(o.tip + 0.19 * shaft_axis, kWidth, kHeight);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const size_t i = (static_cast<size_t>(y) * kWidth + x) * 3;
      int delta = 0;
      for (int k = 0; k < 3; ++k)
        delta += std::abs(int(plain.rgb[i + k]) - int(with_tool.rgb[i + k]));
      if (delta <= 30) continue;
      ++changed;
      const Eigen::Vector2d p(x, y), ab = b - a;
      const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      if ((a + t * ab - p).norm() < 12) ++near_shaft;
    }
  EXPECT_GT(changed, 200);
  EXPECT_GE(near_shaft, 0.95 * changed);
}

TEST(MeshViewTest, TheInstrumentsShadowDarkensTheTissueUnderIt) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  SceneView s("sphere-palpation-256");
  // The probe upright, 1 cm above the sphere a little toward the camera (the key light comes
  // from the camera's side, so the shadow falls behind the tool, over the top).
  const double radius = s.scene.mesh.radius;
  const Eigen::Vector3d toward_camera = (s.view->eye() - Eigen::Vector3d::Zero()).normalized();
  const Eigen::Vector3d normal =
      (Eigen::Vector3d::UnitZ() +
       0.6 * (toward_camera - toward_camera.z() * Eigen::Vector3d::UnitZ()))
          .normalized();
  Overlay o;
  o.show_stylus = true;
  o.tip = (radius + 0.01) * normal;
  // Where the light's ray through a point of the shaft meets the sphere, at a spot the camera
  // sees (facing it).
  const geometry::Bvh bvh(s.mesh.surface);
  geometry::RayHit hit;
  for (double up = 0.005; up < 0.06; up += 0.0025) {
    const Eigen::Vector3d on_shaft = o.tip + Eigen::Vector3d(0, 0, up);
    hit = bvh.FirstHit(s.mesh.surface.positions, on_shaft,
                       on_shaft - 0.5 * s.view->light_direction());
    if (hit.triangle >= 0 &&
        hit.point.normalized().dot((s.view->eye() - hit.point).normalized()) > 0.4 &&
        (hit.point - o.tip).norm() > 0.012)
      break;
    hit.triangle = -1;
  }
  ASSERT_GE(hit.triangle, 0) << "the shaft's shadow must fall on the sphere where it is seen";
  const Eigen::Vector2d at = s.view->Project(hit.point, kWidth, kHeight);
  // Shadows off: the tool does not cover that spot (so a change there is its shadow).
  s.view->SetQuality(Quality::kLow);
  s.view->Draw(kWidth, kHeight, {});
  const double low_plain = Luminance((*surface)->ReadPixels(), at, 2);
  s.view->Draw(kWidth, kHeight, o);
  EXPECT_NEAR(Luminance((*surface)->ReadPixels(), at, 2), low_plain, 2.0);
  // Shadows on: darker there with the tool than without.
  s.view->SetQuality(Quality::kHigh);
  s.view->Draw(kWidth, kHeight, {});
  const double lit = Luminance((*surface)->ReadPixels(), at, 2);
  s.view->Draw(kWidth, kHeight, o);
  const RgbImage shadowed = (*surface)->ReadPixels();
  Keep(shadowed, "shadow");

  EXPECT_LT(Luminance(shadowed, at, 2), 0.8 * lit) << at.transpose();
}

TEST(MeshViewTest, ATurnOfThePhysicsLimbTurnsTheSkinsPatternByTheSameAngle) {
  // End-on, along the limb's axis from beyond the wrist, the skin's pattern alone (no light):
  // turning the physics limb by 30° about its axis must turn the image by 30° about the axis's
  // image, and no other angle may match as well.
  constexpr int kSize = 256;
  auto surface = GlSurface::CreateHeadless(kSize, kSize);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  SceneView s("arm-torsion");
  const double length = s.scene.mesh.limb.length;
  const Eigen::Vector3d axis_end(0, 0, length);
  s.view->SetCamera(axis_end + Eigen::Vector3d(0, 0, 0.12), axis_end, Eigen::Vector3d::UnitY());
  Overlay pattern;
  pattern.albedo_only = true;
  s.view->Draw(kSize, kSize, pattern);
  const RgbImage rest = (*surface)->ReadPixels();
  const double angle = 30 * std::numbers::pi / 180;
  std::vector<int32_t> all;
  std::vector<geometry::Vec3> turned;
  for (size_t i = 0; i < s.mesh.surface.positions.size(); ++i) {
    all.push_back(static_cast<int32_t>(i));
    turned.push_back(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()) *
                     s.mesh.surface.positions[i]);
  }
  s.view->Apply(all, turned);
  s.view->Draw(kSize, kSize, pattern);
  const RgbImage after = (*surface)->ReadPixels();
  Keep(rest, "pattern-rest");
  Keep(after, "pattern-turned");
  // Compare `after` with `rest` turned by a about the axis's image, over a ring of the cap.
  const Eigen::Vector2d c = s.view->Project(axis_end, kSize, kSize);
  const auto mismatch = [&](double a) {
    double sum = 0;
    int n = 0;
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const Eigen::Vector2d p = Eigen::Vector2d(x, y) - c;
        if (p.norm() < 12 || p.norm() > 70) continue;
        const Eigen::Vector2d q = Eigen::Rotation2Dd(-a) * p + c;
        const int qx = static_cast<int>(std::lround(q.x())),
                  qy = static_cast<int>(std::lround(q.y()));
        if (qx < 0 || qy < 0 || qx >= kSize || qy >= kSize) continue;
        const size_t i = (static_cast<size_t>(y) * kSize + x) * 3,
                     j = (static_cast<size_t>(qy) * kSize + qx) * 3;
        for (int k = 0; k < 3; ++k) sum += std::abs(int(after.rgb[i + k]) - int(rest.rgb[j + k]));
        ++n;
      }
    return n ? sum / n : 1e9;
  };
  double best = 1e9, best_angle = 0;
  for (int deg = -60; deg <= 60; ++deg) {
    const double m = mismatch(deg * std::numbers::pi / 180);
    if (m < best) best = m, best_angle = deg;
  }
  EXPECT_NEAR(std::abs(best_angle), 30, 2) << "best match at " << best_angle << " deg";
  EXPECT_LT(best, 0.5 * mismatch(0)) << "the pattern must have turned visibly";
}

std::vector<std::string> AllScenes() {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(sim::ScenesDirectory()))
    if (entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

// The axis-aligned box around `points`: lo, hi.
std::pair<Eigen::Vector3d, Eigen::Vector3d> Bounds(const std::vector<geometry::Vec3>& points) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  return {lo, hi};
}

// The frame every scene test draws: the instrument 1 cm above the tissue's top, guidance on.
Overlay SceneOverlay(const SceneView& s) {
  const auto [lo, hi] = Bounds(s.mesh.surface.positions);
  Overlay o;
  o.show_stylus = true;
  const Eigen::Vector3d up = s.view->visual().up;
  o.tip = 0.5 * (lo + hi) + (0.5 * (hi - lo).dot(up) + 0.01) * up;
  if (s.view->visual().instrument == sim::Instrument::kGrip)
    o.tip = Eigen::Vector3d(0, hi.y() + 0.005, s.scene.mesh.limb.length - 0.02);
  o.orientation = Eigen::Quaterniond::FromTwoVectors(
      Eigen::Vector3d::UnitZ(), (up + Eigen::Vector3d(0.3, 0.2, 0.1)).normalized());
  o.force = 0.5 * up;
  o.guidance.show = false;
  return o;
}

// The table's shadows are shaded only within polygons bounding what casts them (the tissue's
// surface; the instrument's parts, handle and jaws included): each bound gives the image that
// shading the whole table gives, at every scene, at medium and high. The tissue's is checked
// without the instrument, the instrument's with it (SetCatchersCoverTable).
TEST(MeshViewTest, TheTablesShadowsAreWholeWithinTheirBounds) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  for (const std::string& name : AllScenes()) {
    SCOPED_TRACE(name);
    SceneView s(name);
    const Overlay with_tool = SceneOverlay(s);
    Overlay no_tool = with_tool;
    no_tool.show_stylus = false;
    for (Quality q : {Quality::kMedium, Quality::kHigh}) {
      SCOPED_TRACE(QualityName(q));
      s.view->SetQuality(q);
      std::vector<RgbImage> bounded;
      for (const Overlay& overlay : {no_tool, with_tool}) {
        SCOPED_TRACE(overlay.show_stylus ? "the instrument's bound" : "the tissue's bound");
        s.view->SetCatchersCoverTable(false);
        s.view->Draw(kWidth, kHeight, overlay);
        bounded.push_back((*surface)->ReadPixels());
        s.view->SetCatchersCoverTable(true);
        s.view->Draw(kWidth, kHeight, overlay);
        const RgbImage whole = (*surface)->ReadPixels();
        s.view->SetCatchersCoverTable(false);
        Keep(bounded.back(), "catchers-" + name + "-" + QualityName(q));
        EXPECT_EQ(Compare(bounded.back(), whole, Eigen::Vector4d::Zero(), 30).changed, 0)
            << "pixels where a bound cut a shadow off";
      }
      // Not a vacuous comparison: the instrument's shadow darkens the table somewhere.
      EXPECT_GT(Compare(bounded[1], bounded[0], Eigen::Vector4d::Zero(), 30).changed, 200);
    }
  }
}

TEST(MeshViewTest, EverySceneDrawsWithoutBlankOrBlackFrames) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  const std::vector<std::string> scenes = AllScenes();
  ASSERT_GE(scenes.size(), 6u);
  for (const std::string& name : scenes) {
    SCOPED_TRACE(name);
    SceneView s(name);
    for (Quality q : {Quality::kLow, Quality::kHigh}) {
      s.view->SetQuality(q);
      s.view->Draw(kWidth, kHeight, {});
      const RgbImage empty = (*surface)->ReadPixels();
      Overlay o = SceneOverlay(s);
      o.guidance.show = true;
      o.guidance.twist = s.scene.task.kind == scoring::TaskKind::kTwist;
      o.guidance.target = s.scene.task.target;
      o.guidance.tolerance = s.scene.task.tolerance;
      o.guidance.current = 0.6 * s.scene.task.target;
      o.guidance.force_n = 1.2;
      o.guidance.force_limit_n = s.scene.task.force_limit;
      o.guidance.device_limit_n = 3.3;
      o.hud = {"vsurg station  " + name};
      s.view->Draw(kWidth, kHeight, o);
      const RgbImage image = (*surface)->ReadPixels();
      if (q == Quality::kHigh) Keep(image, "scene-" + name);
      // No black pixel anywhere (the background and the unlit table are not black; a NaN in a
      // shader comes out black or undefined), many colours, the tissue and tool on screen.
      int black = 0;
      for (size_t i = 0; i + 2 < image.rgb.size(); i += 3)
        if (image.rgb[i] + image.rgb[i + 1] + image.rgb[i + 2] == 0) ++black;
      EXPECT_EQ(black, 0);
      EXPECT_GT(DistinctColours(image), 300);
      EXPECT_GT(Compare(empty, image).changed, 300) << "the instrument and HUD must show";
      for (const auto& p : s.view->visual_positions()) ASSERT_TRUE(p.allFinite());
    }
  }
}

// Below high the station draws the visual model's coarser surface (about a quarter of the
// triangles): it is the same closed, outward skin, it follows the physics surface as the fine
// one does (a moved tissue stays drawn where the fine surface would be), and the frame looks the
// same: silhouettes within about a pixel, shading within a few levels.
TEST(MeshViewTest, TheCoarseSurfaceBelowHighDrawsWhatTheFineOneDraws) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  int with_coarse = 0;
  for (const std::string& name : AllScenes()) {
    SCOPED_TRACE(name);
    SceneView s(name);
    const sim::VisualModel& v = s.view->visual();
    if (v.coarse_surface.positions.empty()) continue;  // an imported visual mesh
    ++with_coarse;
    const double ratio = double(v.coarse_surface.triangles.size()) / v.surface.triangles.size();
    EXPECT_GT(ratio, 0.2);
    EXPECT_LT(ratio, 0.6);
    const geometry::TopologyReport topology = geometry::CheckTopology(v.coarse_surface);
    EXPECT_TRUE(topology.Closed());
    EXPECT_TRUE(topology.ConsistentlyOriented());
    EXPECT_GT(geometry::SignedVolume(v.coarse_surface), 0);
    // The tissue pressed in: every physics vertex 3 mm down and squeezed toward the middle
    // (something no rest image could match), drawn both ways at medium.
    std::vector<int32_t> all(s.mesh.surface.positions.size());
    std::vector<geometry::Vec3> moved(all.size());
    Eigen::Vector3d mid = Eigen::Vector3d::Zero();
    for (const auto& p : s.mesh.surface.positions) mid += p / double(all.size());
    for (size_t i = 0; i < all.size(); ++i) {
      all[i] = static_cast<int32_t>(i);
      const geometry::Vec3& p = s.mesh.surface.positions[i];
      moved[i] = mid + 0.9 * (p - mid) - Eigen::Vector3d(0, 0, 0.003);
    }
    ASSERT_GT(s.view->Apply(all, moved), 0);
    s.view->SetQuality(Quality::kMedium);
    s.view->SetCoarseBelowHigh(false);
    s.view->Draw(kWidth, kHeight, SceneOverlay(s));
    const RgbImage fine = (*surface)->ReadPixels();
    const size_t fine_vertices = s.view->visual_positions().size();
    s.view->SetCoarseBelowHigh(true);
    s.view->Draw(kWidth, kHeight, SceneOverlay(s));
    const RgbImage coarse = (*surface)->ReadPixels();
    EXPECT_LT(s.view->visual_positions().size(), fine_vertices) << "the coarse surface is drawn";
    for (const auto& p : s.view->visual_positions()) ASSERT_TRUE(p.allFinite());
    Keep(coarse, "coarse-" + name);
    EXPECT_LT(MeanDifference(fine, coarse), 1.5) << "mean difference per channel";
    EXPECT_LT(Compare(fine, coarse, Eigen::Vector4d::Zero(), 48).changed, kWidth * kHeight / 100)
        << "pixels that differ visibly";
    // And at high the fine surface again.
    s.view->SetQuality(Quality::kHigh);
    s.view->Draw(kWidth, kHeight, SceneOverlay(s));
    EXPECT_EQ(s.view->visual_positions().size(), fine_vertices);
  }
  EXPECT_GE(with_coarse, 5) << "limbs and refined organs have a coarse surface";
}

TEST(MeshViewTest, EverySceneMatchesItsReferenceImage) {
  constexpr int kW = 320, kH = 200;
  auto surface = GlSurface::CreateHeadless(kW, kH);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  const std::string folder = std::string(VSURG_SOURCE_DIR) + "/tests/data/render";
  const bool update = std::getenv("VSURG_UPDATE_RENDER_REFERENCES") != nullptr;
  for (const std::string& name : AllScenes()) {
    SCOPED_TRACE(name);
    SceneView s(name);
    s.view->Draw(kW, kH, SceneOverlay(s));
    const RgbImage image = (*surface)->ReadPixels();
    const std::string path = folder + "/" + name + ".png";
    if (update) {
      std::filesystem::create_directories(folder);
      ASSERT_TRUE(WriteRgbPng(path, kW, kH, image.rgb).ok());
      continue;
    }
    auto reference = ReadRgbPng(path);
    ASSERT_TRUE(reference.ok()) << path << ": " << reference.error().message
                                << " (VSURG_UPDATE_RENDER_REFERENCES=1 writes it)";
    ASSERT_EQ(reference->width, kW);
    ASSERT_EQ(reference->height, kH);
    // Within a tolerance: a different CPU's rounding may move an edge by a pixel, not the look.
    const Diff diff = Compare(image, *reference, Eigen::Vector4d::Zero(), 48);
    EXPECT_LT(MeanDifference(image, *reference), 2.0) << "mean difference per channel";
    EXPECT_LT(diff.changed, kW * kH / 100) << "pixels that differ visibly";
  }
}

// A shadow pass in which only the tool moved copies back the tissue's depth kept from the last
// pass that drew it: the frame is the one a view drawing everything afresh makes, the tissue's
// shadow on the table and on itself included; and once the tissue moves it is drawn again.
TEST(MeshViewTest, AToolOnlyMoveDrawsWhatAFreshViewDraws) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  for (Quality q : {Quality::kMedium, Quality::kHigh}) {
    SCOPED_TRACE(QualityName(q));
    SceneView kept("arm-torsion"), fresh("arm-torsion");
    kept.view->SetQuality(q);
    fresh.view->SetQuality(q);
    const Overlay before = SceneOverlay(kept);
    Overlay after = before;
    after.tip += 0.02 * kept.view->visual().up + Eigen::Vector3d(0.015, -0.01, 0);
    after.orientation = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) * before.orientation;
    kept.view->Draw(kWidth, kHeight, before);
    const RgbImage first = (*surface)->ReadPixels();
    kept.view->Draw(kWidth, kHeight, after);  // the tool moved, the tissue did not
    const RgbImage reused = (*surface)->ReadPixels();
    fresh.view->Draw(kWidth, kHeight, after);
    const RgbImage afresh = (*surface)->ReadPixels();
    EXPECT_GT(Compare(first, reused).changed, 100) << "the tool moved in the picture";
    EXPECT_EQ(Compare(reused, afresh, Eigen::Vector4d::Zero(), 0).changed, 0);
    // The tissue's middle third squeezed toward its long axis, the tool where it was, its bounding
    // box unchanged (its ends hold it): it and its shadow are drawn again.
    const auto& rest = kept.mesh.surface.positions;
    const auto [lo, hi] = Bounds(rest);
    int along = 0;
    (hi - lo).maxCoeff(&along);
    const Eigen::Vector3d mid = 0.5 * (lo + hi);
    std::vector<int32_t> all(rest.size());
    std::vector<geometry::Vec3> moved(rest);
    int pressed = 0;
    for (size_t i = 0; i < rest.size(); ++i) {
      all[i] = static_cast<int32_t>(i);
      const bool middle = std::abs(rest[i][along] - mid[along]) < (hi - lo)[along] / 6;
      if (!middle) continue;
      // Towards the long axis by a quarter: the outline its shadow casts narrows.
      Eigen::Vector3d across = rest[i] - mid;
      across[along] = 0;
      moved[i] -= 0.25 * across;
      ++pressed;
    }
    const auto [moved_lo, moved_hi] = Bounds(moved);
    ASSERT_GT(pressed, 20);
    ASSERT_EQ(moved_lo, lo);
    ASSERT_EQ(moved_hi, hi);
    ASSERT_GT(kept.view->Apply(all, moved), 0);
    kept.view->Draw(kWidth, kHeight, after);
    const RgbImage kept_moved = (*surface)->ReadPixels();
    SceneView pressed_first("arm-torsion");  // its first frame: the pressed tissue
    pressed_first.view->SetQuality(q);
    ASSERT_GT(pressed_first.view->Apply(all, moved), 0);
    pressed_first.view->Draw(kWidth, kHeight, after);
    const RgbImage fresh_moved = (*surface)->ReadPixels();
    EXPECT_GT(Compare(reused, kept_moved).changed, 100) << "the tissue moved in the picture";
    EXPECT_EQ(Compare(kept_moved, fresh_moved, Eigen::Vector4d::Zero(), 0).changed, 0);
  }
}

// Colour (r, g, b, 0–255) at a pixel.
Eigen::Vector3i ColourAt(const RgbImage& image, Eigen::Vector2d at) {
  const size_t i = (static_cast<size_t>(at.y()) * image.width + static_cast<size_t>(at.x())) * 3;
  return {image.rgb[i], image.rgb[i + 1], image.rgb[i + 2]};
}

// A search's summary draws where the lumps were over the pad (a ring as wide as each lump, green
// found, red missed) and the trainee's marks (pins: green on a lump, orange on none); nothing
// else of the image changes, and values that are not finite draw nothing.
TEST(MeshViewTest, ASearchsFindingsAreDrawnOverThePadAtTheLumpsAndTheMarks) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  SceneView s("lump-search");
  s.view->SetQuality(Quality::kLow);
  s.view->Draw(kWidth, kHeight, {});
  const RgbImage plain = (*surface)->ReadPixels();
  const double top = Bounds(s.mesh.surface.positions).second.z();
  const Eigen::Vector3d found(0.02, 0.015, top), missed(-0.03, 0.0, top), stray(0.0, -0.035, top);
  Overlay o;
  o.findings.rings = {{found, found - Eigen::Vector3d(0, 0, 0.015), 0.006, true},
                      {missed, missed - Eigen::Vector3d(0, 0, 0.01), 0.005, false},
                      {Eigen::Vector3d::Constant(std::nan("")), found, 0.005, false}};
  o.findings.pins = {{found + Eigen::Vector3d(0.002, 0.001, 0), 0},
                     {stray, -1},
                     {Eigen::Vector3d(std::nan(""), 0, 0), -1}};
  s.view->Draw(kWidth, kHeight, o);
  const RgbImage drawn = (*surface)->ReadPixels();
  Keep(drawn, "findings");
  const auto project = [&](const Eigen::Vector3d& p) {
    return s.view->Project(p, kWidth, kHeight);
  };
  // Each ring's near edge (toward the camera, which looks from -y) in its colour.
  const Eigen::Vector3i green = ColourAt(drawn, project(found + Eigen::Vector3d(0, -0.006, 0.001)));
  const Eigen::Vector3i red = ColourAt(drawn, project(missed + Eigen::Vector3d(0, -0.005, 0.001)));
  EXPECT_GT(green.y(), green.x() + 60) << green.transpose();
  EXPECT_GT(red.x(), red.y() + 80) << red.transpose();
  // The false mark's pin, its head 8 mm up, orange.
  const Eigen::Vector3i orange = ColourAt(drawn, project(stray + Eigen::Vector3d(0, 0, 0.008)));
  EXPECT_GT(orange.x(), 200) << orange.transpose();
  EXPECT_GT(orange.x(), orange.z() + 120) << orange.transpose();
  // What changed lies around the marks: within the box of the rings and pins.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const Eigen::Vector3d& c : {found, missed, stray})
    for (const Eigen::Vector3d& d :
         {Eigen::Vector3d(0.009, 0, 0), Eigen::Vector3d(-0.009, 0, 0), Eigen::Vector3d(0, 0.009, 0),
          Eigen::Vector3d(0, -0.009, 0), Eigen::Vector3d(0, 0, 0.011)})
      lo = lo.cwiseMin(project(c + d)), hi = hi.cwiseMax(project(c + d));
  const Diff d = Compare(plain, drawn, Eigen::Vector4d(lo.x(), lo.y(), hi.x(), hi.y()));
  EXPECT_GT(d.changed, 150);
  EXPECT_EQ(d.inside, d.changed);
}

TEST(QualityGovernorTest, StepsDownWhenFramesRunLongAndNeverBackToALevelTooSlow) {
  QualityGovernor g(Quality::kHigh, 16.7);
  for (int i = 0; i < 30; ++i) g.Update(25);
  EXPECT_EQ(g.level(), Quality::kMedium);
  for (int i = 0; i < 30; ++i) g.Update(12);
  EXPECT_EQ(g.level(), Quality::kMedium);
  for (int i = 0; i < 600; ++i) g.Update(3);  // fast, but high was too slow: stays
  EXPECT_EQ(g.level(), Quality::kMedium);
  for (int i = 0; i < 30; ++i) g.Update(40);
  EXPECT_EQ(g.level(), Quality::kLow);
  for (int i = 0; i < 30; ++i) g.Update(400);
  EXPECT_EQ(g.level(), Quality::kLow);  // no level below low
  QualityGovernor up(Quality::kLow, 16.7);
  for (int i = 0; i < 30; ++i) up.Update(3);
  EXPECT_EQ(up.level(), Quality::kLow) << "up only after 120 fast frames";
  for (int i = 0; i < 90; ++i) up.Update(3);
  EXPECT_EQ(up.level(), Quality::kMedium);
  // The tail decides: two slow frames in thirty step down (a p90 rule would keep the level and
  // its p99 over the budget); one does not (a single hitch).
  QualityGovernor tail(Quality::kMedium, 16.7);
  for (int i = 0; i < 30; ++i) tail.Update(i == 7 ? 30 : 9);
  EXPECT_EQ(tail.level(), Quality::kMedium);
  for (int i = 0; i < 30; ++i) tail.Update(i == 7 || i == 20 ? 30 : 9);
  EXPECT_EQ(tail.level(), Quality::kLow);
  // Never above the level chosen before the trial, however fast the frames.
  QualityGovernor capped(Quality::kMedium, 16.7, Quality::kMedium);
  for (int i = 0; i < 600; ++i) capped.Update(2);
  EXPECT_EQ(capped.level(), Quality::kMedium);
}

// The level a trial starts at, from frames drawn before it: the highest whose p90 is within the
// share of the budget; a level not probed counts as too slow; low when nothing fits.
TEST(QualityGovernorTest, TheTrialStartsAtTheHighestLevelWhoseProbeFitsItsShare) {
  const auto probe = [](std::vector<double> high, std::vector<double> medium) {
    std::array<std::vector<double>, 3> p;
    p[static_cast<size_t>(Quality::kHigh)] = std::move(high);
    p[static_cast<size_t>(Quality::kMedium)] = std::move(medium);
    return p;
  };
  const std::vector<double> fast(12, 6.0), slow(12, 14.0);
  EXPECT_EQ(StartingQuality(probe(fast, {}), 16.7), Quality::kHigh);
  EXPECT_EQ(StartingQuality(probe(slow, fast), 16.7), Quality::kMedium);
  EXPECT_EQ(StartingQuality(probe(slow, slow), 16.7), Quality::kLow);
  EXPECT_EQ(StartingQuality(probe(slow, {}), 16.7), Quality::kLow) << "medium not probed";
  EXPECT_EQ(StartingQuality(probe(slow, {}), 16.7, 0.9), Quality::kHigh) << "a wider share";
  // The 90th percentile, not the mean: two slow frames in twelve are the tail.
  std::vector<double> tail(12, 4.0);
  tail[3] = tail[9] = 15.0;
  EXPECT_EQ(StartingQuality(probe(tail, fast), 16.7), Quality::kMedium);
  tail[9] = 4.0;  // one: the p90 of twelve is the second-slowest
  EXPECT_EQ(StartingQuality(probe(tail, fast), 16.7), Quality::kHigh);
}

// In a fresh process (a death test's child, re-run from the start): the rasterizer threads
// (llvmpipe-0 … llvmpipe-N-1) Mesa's llvmpipe started for a surface, with `requested` asked for;
// 100 when there are none (another renderer).
int RasterizerThreadsStarted(int requested) {
  ::unsetenv("LP_NUM_THREADS");
  if (RequestSoftwareRenderThreads(requested) != requested) return 101;
  if (RequestSoftwareRenderThreads(requested + 2) != requested) return 102;  // the first wins
  auto surface = GlSurface::CreateHeadless(64, 64);
  if (!surface.ok()) return 103;
  (void)(*surface)->ReadPixels();  // drawn and finished: the renderer is running
  // Each rasterizer thread names itself when it first runs, which on a loaded machine may come
  // after the frame is read: wait for the names (on progress, up to 10 s), not on luck. Fewer
  // threads than asked never all appear, and the count returned then says how many did.
  const auto named = [] {
    int n = 0;
    for (const std::string& name : test::ThreadNames()) n += name.rfind("llvmpipe-", 0) == 0;
    return n;
  };
  int started = 0;
  test::Eventually(10, [&] { return (started = named()) >= requested; });
  return started > 0 ? started : 100;
}

// vsurg-station --render-threads: the software renderer starts as many rasterizer threads as the
// station asks for, not one per core, unless the environment already chose.
TEST(GlSurfaceDeathTest, ASoftwareRendererStartsTheRasterizerThreadsAskedFor) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");  // a fresh process: no renderer started yet
  EXPECT_EXIT(std::exit(RasterizerThreadsStarted(3)), ::testing::ExitedWithCode(3), "");
  EXPECT_EXIT(std::exit(RasterizerThreadsStarted(5)), ::testing::ExitedWithCode(5), "");
}

TEST(GlSurfaceTest, RejectsAbsurdSizes) {
  EXPECT_FALSE(GlSurface::CreateHeadless(0, 100).ok());
  EXPECT_FALSE(GlSurface::CreateHeadless(100000, 100).ok());
}

}  // namespace
}  // namespace vsurg::client
