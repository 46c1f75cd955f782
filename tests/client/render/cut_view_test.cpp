// The station's view of a cut (MeshView::ApplyFaces): a scripted good hand cuts the circle out of
// scenes/pattern-cut.json through the simulation, and its visual frames (moved vertices and the
// cut's faces) are applied to the view as the station applies its SceneFrames. The freed piece
// leaves a hole the table shows through; the patch outside the cut is drawn as before; the marked
// circle is drawn on the skin, and the hole's rim shows its wall in the dermis' red. Two hands:
// the second device's grasper is drawn where it is, beside the first hand's scalpel.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "client/render/cut_walls.h"
#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "common/core/image.h"
#include "common/sim/cut_trainee.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/visual_model.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::client {
namespace {

constexpr int kSize = 320;

void KeepImage(const RgbImage& image, const std::string& name) {
  if (const char* dir = std::getenv("VSURG_RENDER_OUT"))
    (void)WriteRgbPng(std::string(dir) + "/" + name + ".png", image.width, image.height, image.rgb);
}

// The mean colour difference over the pixels within `radius` of `at`.
double MeanDifference(const RgbImage& a, const RgbImage& b, const Eigen::Vector2d& at,
                      double radius) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      if ((Eigen::Vector2d(x, y) - at).norm() > radius) continue;
      const size_t i = (static_cast<size_t>(y) * a.width + x) * 3;
      for (int k = 0; k < 3; ++k) sum += std::abs(int(a.rgb[i + k]) - int(b.rgb[i + k]));
      ++n;
    }
  return n ? sum / n : 0;
}

// scenes/pattern-cut.json's patch in a MeshView on a headless width × height surface, seen from
// `eye` toward `centre`.
struct CutView {
  std::unique_ptr<GlSurface> surface;
  sim::Scene scene;
  std::optional<MeshView> view;
};
void OpenCutView(int width, int height, const Eigen::Vector3d& eye, const Eigen::Vector3d& centre,
                 CutView& out) {
  auto surface = GlSurface::CreateHeadless(width, height);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  out.surface = std::move(*surface);
  auto scene = sim::LoadSceneByName("pattern-cut");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  out.scene = *scene;
  auto mesh = sim::BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok());
  auto visual = sim::BuildVisualModel(*scene, mesh->surface);
  ASSERT_TRUE(visual.ok());
  ASSERT_TRUE(visual->physics_drawn);
  ASSERT_EQ(visual->second_instrument, sim::Instrument::kGrasper);
  out.view.emplace(mesh->surface, std::move(*visual));
  out.view->SetCamera(eye, centre, {0, 0, 1});
}

TEST(CutViewTest, TheCutPieceLeavesAHoleAndThePatchAroundItStays) {
  CutView v;
  ASSERT_NO_FATAL_FAILURE(OpenCutView(kSize, kSize, {0.0, -0.09, 0.11}, {0, 0, 0}, v));
  MeshView& view = *v.view;
  Overlay overlay;
  overlay.show_stylus = false;
  view.Draw(kSize, kSize, overlay);
  const RgbImage uncut = v.surface->ReadPixels();
  // The marked circle is drawn on the skin in a marker's violet (blue over red; skin is the other
  // way round), and the skin between it and the middle is not.
  const auto blue_over_red = [&](const RgbImage& im, const Eigen::Vector2d& at) {
    const size_t i =
        (static_cast<size_t>(std::lround(at.y())) * im.width + std::lround(at.x())) * 3;
    return int(im.rgb[i + 2]) - int(im.rgb[i]);
  };
  EXPECT_GT(blue_over_red(uncut, view.Project({0, -0.015, 0}, kSize, kSize)), 30);
  EXPECT_LT(blue_over_red(uncut, view.Project({0, -0.0075, 0}, kSize, kSize)), 0);

  auto sim = sim::Simulation::Create(v.scene, {.threaded = false});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  auto plan = sim::CutTrainee(v.scene, sim::TraineeStyle::kGood);
  ASSERT_TRUE(plan.ok());
  sim::VisualFrame frame;
  int n = 0, faces = 0;
  (*sim)->Replay(*plan, [&](const haptics::StylusSample&, const haptics::ForceCommand&) {
    if (++n % 16 != 0 || !(*sim)->TakeVisualFrame(frame)) return;
    view.Apply(frame.indices, frame.positions);  // the vertices first, as the server sends them
    std::vector<std::array<int32_t, 3>> corners(frame.faces.begin(), frame.faces.end());
    faces += view.ApplyFaces(frame.face_indices, corners);
  });
  EXPECT_GT(faces, 100);
  view.Draw(kSize, kSize, overlay);
  const RgbImage cut = v.surface->ReadPixels();
  KeepImage(uncut, "cut-patch-before");
  KeepImage(cut, "cut-patch-after");
  for (const auto& p : view.visual_positions()) ASSERT_TRUE(p.allFinite());
  // The piece's middle shows the table 4 cm below; the patch's far corner is as it was.
  const Eigen::Vector2d middle = view.Project({0, 0, 0}, kSize, kSize);
  const Eigen::Vector2d corner = view.Project({-0.034, 0.034, 0}, kSize, kSize);
  EXPECT_GT(MeanDifference(uncut, cut, middle, 8), 20.0);
  EXPECT_LT(MeanDifference(uncut, cut, corner, 6), 6.0);
  // The hole's far half faces the camera: its wall shows the dermis' deep red (green and blue
  // under 40% of the red; the skin's are over two thirds of it, the marked line's blue over it).
  const auto dermis = [](const RgbImage& im, const Eigen::Vector2d& at) {
    const size_t i =
        (static_cast<size_t>(std::lround(at.y())) * im.width + std::lround(at.x())) * 3;
    const double r = im.rgb[i], g = im.rgb[i + 1], b = im.rgb[i + 2];
    return r > 60 && g < 0.4 * r && b < 0.4 * r;
  };
  const double t = v.scene.mesh.membrane.thickness;
  std::set<std::pair<long, long>> red;       // pixels, each once
  for (double a = 0.15; a < 3.0; a += 0.01)  // the far half of the circle, from +x round to −x
    for (double r = 0.012; r <= 0.018; r += 2.5e-4) {
      const Eigen::Vector2d at =
          view.Project({r * std::cos(a), r * std::sin(a), -0.25 * t}, kSize, kSize);
      if (dermis(cut, at)) red.emplace(std::lround(at.x()), std::lround(at.y()));
    }
  EXPECT_GT(red.size(), 40u) << "the hole's wall: " << red.size() << " pixels";
  EXPECT_FALSE(dermis(cut, corner));
}

// The walls of a cut sheet, without OpenGL: a straight cut across the middle opens a wall on each
// side of each edge it cut, as tall as the sheet; the frame's rim is none; an uncut sheet none.
TEST(CutWallsTest, ACutOpensAWallOnEachSideAndTheRimNone) {
  tissue::CutMembraneParams p;
  p.cells = 12;
  auto m = tissue::CutMembrane::Create(p);
  ASSERT_TRUE(m.ok()) << m.error().message;
  const auto mesh_of = [&] {
    geometry::TriMesh t;
    t.positions = m->positions();
    for (int f = 0; f < m->FaceCount(); ++f) {
      const auto v = m->face(f).v;
      t.triangles.push_back(m->Removed(f) ? geometry::Triangle{0, 0, 0}
                                          : geometry::Triangle{v[0], v[1], v[2]});
    }
    geometry::ComputeVertexNormals(t);
    return t;
  };
  const geometry::TriMesh rest = mesh_of();
  CutWalls walls(rest.triangles);
  ShapeMesh out;
  walls.Build(rest, p.thickness, out);
  EXPECT_EQ(walls.edges(), 0);
  EXPECT_TRUE(out.indices.empty());
  const int cut = m->Cut({-0.02, 0.0}, {0.02, 0.0});
  ASSERT_GT(cut, 4);
  walls.Build(mesh_of(), p.thickness, out);
  EXPECT_EQ(walls.edges(), 2 * cut);
  ASSERT_EQ(out.positions.size(), 4u * static_cast<size_t>(walls.edges()));
  for (size_t q = 0; q < out.positions.size(); q += 4) {
    EXPECT_NEAR((out.positions[q] - out.positions[q + 1]).norm(), p.thickness, 1e-6);
    EXPECT_NEAR(out.normals[q].z(), 0, 1e-6);  // across the flat sheet, in its plane
  }
  walls.Build(mesh_of(), 0, out);  // no thickness: nothing to draw
  EXPECT_TRUE(out.indices.empty());
}

TEST(CutViewTest, BothHandsInstrumentsAreDrawnWhereTheirDevicesAre) {
  constexpr int kWide = 480, kHigh = 320;
  CutView v;
  ASSERT_NO_FATAL_FAILURE(OpenCutView(kWide, kHigh, {0.0, -0.12, 0.13}, {0, 0, 0.01}, v));
  MeshView& view = *v.view;
  // The scalpel at the circle's start, leaning in from the right; the grasper on the piece's
  // middle, 3 mm up, jaws closed, leaning in from the left.
  Overlay both;
  both.show_stylus = true;
  both.tip = {0.015, 0, -0.001};
  both.orientation = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY());
  both.show_second = true;
  both.second_tip = {0, 0, 0.003};
  both.second_orientation = Eigen::AngleAxisd(-0.6, Eigen::Vector3d::UnitY());
  both.second_grasping = true;
  Overlay one = both;
  one.show_second = false;
  view.Draw(kWide, kHigh, one);
  const RgbImage blade_only = v.surface->ReadPixels();
  view.Draw(kWide, kHigh, both);
  const RgbImage two_hands = v.surface->ReadPixels();
  KeepImage(two_hands, "cut-two-hands");
  // The grasper's jaws at its tip (and its shaft above-left of them) are drawn; the scalpel's
  // tip is as it was, and so is the patch's far corner.
  const Eigen::Vector2d jaws = view.Project({-0.004, 0, 0.01}, kWide, kHigh);
  const Eigen::Vector2d blade = view.Project({0.018, 0, 0.006}, kWide, kHigh);
  const Eigen::Vector2d corner = view.Project({0.034, 0.034, 0}, kWide, kHigh);
  EXPECT_GT(MeanDifference(blade_only, two_hands, jaws, 6), 20.0);
  EXPECT_LT(MeanDifference(blade_only, two_hands, blade, 3), 4.0);
  EXPECT_LT(MeanDifference(blade_only, two_hands, corner, 6), 4.0);
}

}  // namespace
}  // namespace vsurg::client
