// The surface twist room (common/sim/rooms/surface_twist_room.h): forceps twisting an organ's
// surface on its precomputed tables.
#include <cstdlib>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

// organ-surface-twist on its reduced surface-twist table: a scripted trainee grasps the top and
// twists it to 30° within the force limit; the table is cached; the frame shows the organ turned
// about the normal at the jaws while the held bottom stays.
TEST(RoomTest, ForcepsTwistTheOrganOnItsSurfaceTwistTable) {
  namespace fs = std::filesystem;
  const test::TempDir dir("st_cache");
  setenv("VSURG_CACHE_DIR", dir.string().c_str(), 1);
  double peak = 0;
  const scoring::TrialMetrics good = Replay("organ-surface-twist", TraineeStyle::kGood, &peak);
  EXPECT_TRUE(fs::exists(dir / "organ-surface-twist-surface-twist.vrm"));
  ASSERT_TRUE(good.completed);
  EXPECT_LT(good.task_error, 5 * M_PI / 180);
  EXPECT_LE(peak, 3.3 + 1e-9);
  EXPECT_LT(good.peak_force, 3.0);
  EXPECT_EQ(good.overload_events, 0);
  EXPECT_GE(good.score, 8.0);
  // Hold a grasp at the top twisted by 30° and look at the surface.
  auto scene = LoadSceneByName("organ-surface-twist");
  ASSERT_TRUE(scene.ok());
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  unsetenv("VSURG_CACHE_DIR");
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0.0005, 0.0003, 0.06);
  double t = 0;
  auto step = [&](int n) {
    haptics::ForceCommand c;
    for (int i = 0; i < n; ++i) {
      s.time = (t += 1e-3);
      c = (*sim)->OnStylus(s);
      (*sim)->StepDeformation();
    }
    return c;
  };
  step(50);
  s.position.z() = 0.0495;  // on the top
  step(50);
  s.buttons = haptics::kButtonGrasp;
  step(20);
  haptics::ForceCommand c;
  for (int k = 1; k <= 300; ++k) {
    s.orientation =
        Eigen::Quaterniond(Eigen::AngleAxisd(k / 300.0 * M_PI / 6, Eigen::Vector3d::UnitZ()));
    c = step(1);
  }
  c = step(200);
  EXPECT_TRUE(c.grasping);
  EXPECT_NEAR(c.twist, M_PI / 6, 0.01);  // about the contact triangle's normal, not quite z
  EXPECT_GT(c.torque, 0.02);             // N·m: the FEM's stiffness, 0.042 N·m for 30°
  EXPECT_LT(c.torque, 0.2);
  EXPECT_EQ(c.events & haptics::kEventOutsideModel, 0u);
  VisualFrame frame;
  ASSERT_TRUE((*sim)->TakeVisualFrame(frame));
  const auto& rest = (*sim)->rest_mesh().positions;
  double top_turn = 0;
  for (size_t k = 0; k < frame.indices.size(); ++k) {
    const Eigen::Vector3d& x0 = rest[frame.indices[k]];
    const Eigen::Vector3d& x = frame.positions[k];
    if (x0.z() < -0.035) {
      EXPECT_LT((x - x0).norm(), 5e-4) << "a held vertex moved";
    }
    if (x0.z() > 0.04 && x0.head<2>().norm() > 0.01)
      top_turn = std::max(
          top_turn, std::atan2(x0.x() * x.y() - x0.y() * x.x(), x0.x() * x.x() + x0.y() * x.y()));
  }
  EXPECT_GT(top_turn, 0.2);  // rad: the top turns with the jaws (30° at the jaws)
  EXPECT_LT(top_turn, M_PI / 6 + 0.05);
  // Released: back at rest.
  s.buttons = 0;
  step(20);
  ASSERT_TRUE((*sim)->TakeVisualFrame(frame));
  for (size_t k = 0; k < frame.indices.size(); ++k)
    EXPECT_LT((frame.positions[k] - rest[frame.indices[k]]).norm(), 1e-9);
}

}  // namespace
}  // namespace vsurg::sim
