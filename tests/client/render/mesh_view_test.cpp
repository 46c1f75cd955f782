// Headless rendering (EGL surfaceless, Mesa llvmpipe): the arm drawn at rest and twisted by a
// scripted trainee through the real Simulation. The image must not be blank, and it must
// change where the arm is twisted (the wrist end) and not where it is held (the elbow end).
#include <gtest/gtest.h>

#include <set>

#include <Eigen/Geometry>

#include "client/render/gl_surface.h"
#include "client/render/mesh_view.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"

namespace vsurg::client {
namespace {

constexpr int kWidth = 480, kHeight = 320;

// Pixels whose colour changed, and how many of them fall within `box` (x0, y0, x1, y1).
struct Diff {
  int changed = 0, inside = 0;
};

Diff Compare(const RgbImage& a, const RgbImage& b, Eigen::Vector4d box = Eigen::Vector4d::Zero()) {
  Diff d;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const size_t i = (static_cast<size_t>(y) * a.width + x) * 3;
      int delta = 0;
      for (int k = 0; k < 3; ++k) delta += std::abs(int(a.rgb[i + k]) - int(b.rgb[i + k]));
      if (delta > 30) {
        ++d.changed;
        if (x >= box[0] && x <= box[2] && y >= box[1] && y <= box[3]) ++d.inside;
      }
    }
  return d;
}

int DistinctColours(const RgbImage& image) {
  std::set<uint32_t> colours;
  for (size_t i = 0; i + 2 < image.rgb.size(); i += 3)
    colours.insert((uint32_t(image.rgb[i]) << 16) | (uint32_t(image.rgb[i + 1]) << 8) |
                   image.rgb[i + 2]);
  return static_cast<int>(colours.size());
}

TEST(MeshViewTest, TwistedArmChangesTheImageAtTheWristOnly) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  auto scene = sim::LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  auto simulation = sim::Simulation::Create(*scene, {.threaded = false});
  ASSERT_TRUE(simulation.ok()) << simulation.error().message;
  auto trajectory = sim::ScriptedTrainee(*scene, sim::TraineeStyle::kGood);
  ASSERT_TRUE(trajectory.ok());

  MeshView view((*simulation)->rest_mesh());
  view.Draw(kWidth, kHeight, {});
  const RgbImage rest = (*surface)->ReadPixels();
  ASSERT_EQ(rest.width, kWidth);
  ASSERT_EQ(rest.rgb.size(), size_t{kWidth} * kHeight * 3);
  EXPECT_GT(DistinctColours(rest), 50) << "shaded, checkered arm expected";

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

  // On screen, the box around the vertices the twist moved (and 4 px more for the shading of
  // their neighbours), and the box around the held elbow end (vertices that stayed put).
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
  moved_box += Eigen::Vector4d(-4, -4, 4, 4);
  const Diff diff = Compare(rest, twisted, moved_box);
  EXPECT_GT(diff.changed, 500) << "the twist must be visible";
  EXPECT_GE(diff.inside, 0.97 * diff.changed) << "changes only where the arm moved";
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

TEST(MeshViewTest, OverlayDrawsStylusForceAndHud) {
  auto surface = GlSurface::CreateHeadless(kWidth, kHeight);
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  auto scene = sim::LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(scene.ok());
  auto mesh = sim::BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok());
  MeshView view(mesh->surface);
  view.Draw(kWidth, kHeight, {});
  const RgbImage plain = (*surface)->ReadPixels();
  Overlay overlay;
  overlay.show_stylus = true;
  overlay.tip = mesh->surface.positions[0] * 1.2;
  overlay.force = Eigen::Vector3d(0, 0, 2.0);
  overlay.hud = {"rate 1000 hz", "rtt 80 us"};
  view.Draw(kWidth, kHeight, overlay);
  const Diff diff = Compare(plain, (*surface)->ReadPixels());
  EXPECT_GT(diff.changed, 100);
  // Non-finite overlay values are not drawn and do not break the frame.
  overlay.tip = Eigen::Vector3d::Constant(std::nan(""));
  overlay.hud.clear();
  view.Draw(kWidth, kHeight, overlay);
  EXPECT_EQ(Compare(plain, (*surface)->ReadPixels()).changed, 0);
}

TEST(GlSurfaceTest, RejectsAbsurdSizes) {
  EXPECT_FALSE(GlSurface::CreateHeadless(0, 100).ok());
  EXPECT_FALSE(GlSurface::CreateHeadless(100000, 100).ok());
}

}  // namespace
}  // namespace vsurg::client
