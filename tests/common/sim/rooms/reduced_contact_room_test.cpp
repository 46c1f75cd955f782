// The reduced contact room (common/sim/rooms/reduced_contact_room.h): the sphere and organs pressed
// on their precomputed contact tables, a hidden lump among them.
#include <cstdlib>
#include <filesystem>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, ScriptedTraineesPalpateTheReducedSphere) {
  ExpectPalpatedByScriptedTrainees("sphere-palpation-1024");
}

// A scene may leave out the table's rotation correction ("rotation": false): the same press
// feels the same within 1% (the force is the contact's compliance, which the correction does not
// touch) and the surface's shape differs, each point moved along its response without turning.
TEST(RoomTest, ATableWithoutItsRotationCorrectionFeelsTheSameAndMovesItsSurfaceStraight) {
  const test::TempDir dir("sim_rotation");
  auto base = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(base.ok());
  base->mesh.particles = 256;
  const auto pressed = [&](bool rotation, std::vector<geometry::Vec3>& surface) {
    Scene scene = *base;
    scene.name = rotation ? "rotation" : "straight";
    scene.region.reduced.rotation = rotation;
    auto sim = Simulation::Create(scene, {.threaded = false, .cache_dir = dir.string()});
    EXPECT_TRUE(sim.ok()) << sim.error().message;
    haptics::StylusSample s;
    haptics::ForceCommand c;
    const Eigen::Vector3d top(0.0005, 0.0003, 0.05);
    for (int i = 0; i < 400; ++i) {
      s.time = i * 1e-3;
      s.position = top - std::clamp((i - 100) * 1e-4, -0.01, 0.012) * Eigen::Vector3d::UnitZ();
      c = (*sim)->OnStylus(s);
      (*sim)->StepDeformation();
    }
    VisualFrame frame;
    EXPECT_TRUE((*sim)->TakeVisualFrame(frame));
    surface = (*sim)->LastFramePositions();
    EXPECT_TRUE(c.contact);
    return c.force;
  };
  std::vector<geometry::Vec3> turned, straight;
  const Eigen::Vector3d f_turned = pressed(true, turned), f_straight = pressed(false, straight);
  EXPECT_GT(f_turned.z(), 1.0);
  // The proxy meets the surface where the table puts it: the contact point's own turn moves it a
  // little (0.3% at 1.8 N on this press).
  EXPECT_LT((f_turned - f_straight).norm(), 0.01 * f_turned.norm());
  ASSERT_EQ(turned.size(), straight.size());
  double apart = 0;
  for (size_t i = 0; i < turned.size(); ++i)
    apart = std::max(apart, (turned[i] - straight[i]).norm());
  EXPECT_GT(apart, 1e-5) << "the correction turned nothing";
  EXPECT_LT(apart, 3e-3);
}

// A hidden lump (10 mm across, five times as stiff, its centre 15 mm under the top) in a reduced
// sphere: pressed at the top the same 4 mm, the tissue pushes back harder than without it, and
// the same press 30 mm aside feels hardly any of that difference.
TEST(RoomTest, AHiddenLumpPushesBackHarderAboveItThanAside) {
  const test::TempDir dir("sim_lump");
  auto base = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(base.ok());
  base->mesh.particles = 256;
  base->region.reduced.fem_cells = 16;
  const auto pressed = [&](bool lump, const Eigen::Vector3d& at) {
    Scene scene = *base;
    scene.name = lump ? "lump" : "no-lump";
    if (lump) scene.inclusions = {{{0, 0, 0.035}, 0.005, 5}};
    auto sim = Simulation::Create(scene, {.threaded = false, .cache_dir = dir.string()});
    EXPECT_TRUE(sim.ok()) << sim.error().message;
    const Eigen::Vector3d n = at.normalized();
    haptics::StylusSample s;
    haptics::ForceCommand c;
    for (int i = 0; i < 400; ++i) {
      s.time = i * 1e-3;
      const double depth = std::clamp((i - 100) * 1e-4, -0.01, 0.004);  // m into the surface
      s.position = at - depth * n;
      c = (*sim)->OnStylus(s);
      (*sim)->StepDeformation();
    }
    EXPECT_TRUE(c.contact);
    EXPECT_TRUE(c.force.allFinite());
    return c.force.dot(n);
  };
  const Eigen::Vector3d top(0.0005, 0.0003, 0.05);
  const Eigen::Vector3d aside = 0.05 * Eigen::Vector3d(0.03, 0, 0.04).normalized();
  // The tool's 300 N/m proxy spring is in series with the tissue: the force shows a part of the
  // tissue's own contrast above the lump (1.09 at these 16 cells, tissue_test).
  const double over = pressed(true, top), plain = pressed(false, top);
  EXPECT_GT(over, 1.02 * plain) << over << " N over the lump, " << plain << " N without";
  const double side = pressed(true, aside) / pressed(false, aside);
  EXPECT_NEAR(side, 1.0, (over / plain - 1) / 3) << "aside: " << side;
}

TEST(RoomTest, AReducedSphereSinksUnderTheToolAndCachesItsTable) {
  namespace fs = std::filesystem;
  const test::TempDir dir("sim_cache");
  auto scene = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(scene.ok());
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  EXPECT_TRUE(fs::exists(dir / "sphere-palpation-1024-contact.vrm"));
  const auto& rest = (*sim)->rest_mesh().positions;
  int pole = 0;
  for (int i = 0; i < static_cast<int>(rest.size()); ++i)
    if (rest[i].z() > rest[pole].z()) pole = i;
  // Approach from above, then hold the tip 4 mm into the top for 0.3 s.
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0.0005, 0.0003, 0.06);
  for (int i = 0; i < 100; ++i) s.time = i * 1e-3, (*sim)->OnStylus(s), (*sim)->StepDeformation();
  haptics::ForceCommand c;
  for (int i = 100; i < 400; ++i) {
    s.time = i * 1e-3;
    s.position.z() = std::max(0.046, 0.06 - (i - 100) * 1e-4);
    c = (*sim)->OnStylus(s);
    (*sim)->StepDeformation();
  }
  EXPECT_TRUE(c.contact);
  ASSERT_TRUE(c.force.allFinite());
  EXPECT_GT(c.force.z(), 0.1);  // the sphere pushes the tool back up
  // The station's local model renders the proxy's 300 N/m in series with the soft tissue.
  EXPECT_LT(-c.local.jacobian(2, 2), 0.8 * 300) << c.local.jacobian;
  EXPECT_GT(-c.local.jacobian(2, 2), 10) << c.local.jacobian;
  VisualFrame frame;
  ASSERT_TRUE((*sim)->TakeVisualFrame(frame));
  double pole_dz = 0;
  for (size_t k = 0; k < frame.indices.size(); ++k)
    if (frame.indices[k] == pole) pole_dz = frame.positions[k].z() - rest[pole].z();
  // The surface gives way under the tool (the proxy sits on the moved surface, between the tip
  // and where the surface was), and the far side does not move.
  EXPECT_LT(pole_dz, -0.001);
  EXPECT_GT(pole_dz, -0.004 - 1e-9);
  for (size_t k = 0; k < frame.indices.size(); ++k)
    EXPECT_LT((frame.positions[k] - rest[frame.indices[k]]).norm(), 0.0045);
  // Another session of the scene reads the file (or shares the table in memory).
  auto again = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(again.ok());
}

TEST(RoomTest, SessionsOfReducedScenesAreBuiltSideBySide) {
  // Two sessions of one reduced scene and one of another, created at once with an empty cache:
  // all three are built (one table computed per scene, the other session of the first scene
  // waiting for it), nothing deadlocks.
  namespace fs = std::filesystem;
  const test::TempDir dir("side");
  auto sphere = LoadSceneByName("sphere-palpation-1024");
  auto kidney = LoadSceneByName("kidney-palpation");
  ASSERT_TRUE(sphere.ok() && kidney.ok());
  std::atomic<int> built{0};
  std::vector<std::thread> threads;
  for (const Scene* scene : {&*sphere, &*sphere, &*kidney})
    threads.emplace_back([&, scene] {
      auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
      if (sim.ok()) ++built;
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(built.load(), 3);
  EXPECT_TRUE(fs::exists(dir / "sphere-palpation-1024-contact.vrm"));
  EXPECT_TRUE(fs::exists(dir / "kidney-palpation-contact.vrm"));
}

TEST(RoomTest, TheLocalModelPredictsTheNextUpdateOnAReducedSphere) {
  // A station renders F₀ + J·(x − x₀) between two server updates. With a 5 ms network delay and
  // the tool pressing on at 5 cm/s, the tip goes 0.25 mm deeper before the next update: compare
  // the force the local model predicts there with the force the server then answers, for the
  // series stiffness the simulation now sends (after) and the proxy spring alone (before).
  namespace fs = std::filesystem;
  const test::TempDir dir("lm_cache");
  auto scene = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(scene.ok());
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0.0005, 0.0003, 0.06);
  double t = 0;
  auto hold = [&](double z, int samples) {
    haptics::ForceCommand c;
    s.position.z() = z;
    for (int i = 0; i < samples; ++i) {
      s.time = (t += 1e-3);
      c = (*sim)->OnStylus(s);
      (*sim)->StepDeformation();
    }
    return c;
  };
  hold(0.06, 100);
  for (double z = 0.06; z > 0.047; z -= 1e-4) hold(z, 1);
  // Settled 3 mm into the surface, past the safety filter's start-up ramp (0.5 s).
  const haptics::ForceCommand at0 = hold(0.047, 1000);
  ASSERT_TRUE(at0.contact);
  const Eigen::Vector3d step(0, 0, -0.00025);
  const haptics::ForceCommand at1 = hold(0.047 - 0.00025, 300);  // the server's next answer
  const Eigen::Vector3d after = at0.force + at0.local.jacobian * step;
  const Eigen::Vector3d before =
      at0.force - scene->haptics.proxy.stiffness * Eigen::Vector3d::UnitZ() * step.z();
  const double err_after = (after - at1.force).norm(), err_before = (before - at1.force).norm();
  RecordProperty("force_error_before_n", std::to_string(err_before));
  RecordProperty("force_error_after_n", std::to_string(err_after));
  std::printf(
      "local model over 0.25 mm (5 ms at 5 cm/s): error before %.4f N, after %.4f N, "
      "force step %.4f N\n",
      err_before, err_after, (at1.force - at0.force).norm());
  EXPECT_LT(err_after, 0.25 * err_before);
  EXPECT_LT(err_after, 0.1 * (at1.force - at0.force).norm());
}

// A contact where the reduced table has no response of its own (next to the table the sphere
// rests on, whose vertices are held): the nearest precomputed contact answers, the force stays
// bounded and finite, and every such sample carries kEventOutsideModel; a contact on the top
// does not.
TEST(RoomTest, AContactOutsideTheReducedModelIsBoundedAndFlagged) {
  namespace fs = std::filesystem;
  const test::TempDir dir("om_cache");
  auto scene = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(scene.ok());
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  haptics::StylusSample s;
  double t = 0;
  // Press straight in along `dir` to `depth` past the rest surface at `at`; count the samples in
  // contact and those flagged.
  auto press = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& inward, int& contact,
                   int& flagged, double& peak) {
    contact = flagged = 0;
    peak = 0;
    for (int i = 0; i <= 800; ++i) {
      const double d = std::min(0.004, -0.01 + i * 2e-5);  // from 1 cm out to 4 mm in
      s.position = at + d * inward;
      s.time = (t += 1e-3);
      const haptics::ForceCommand c = (*sim)->OnStylus(s);
      (*sim)->StepDeformation();
      ASSERT_TRUE(c.force.allFinite());
      peak = std::max(peak, c.force.norm());
      contact += c.contact;
      flagged += (c.events & haptics::kEventOutsideModel) != 0;
    }
    s.position = at - 0.05 * inward;  // away, out of contact
    for (int i = 0; i < 50; ++i)
      s.time = (t += 1e-3), (*sim)->OnStylus(s), (*sim)->StepDeformation();
  };
  int contact = 0, flagged = 0;
  double peak = 0;
  // The side of the ball 4 cm below its centre (the held bottom fifth ends 3 cm below it).
  const double z = -0.04, r = std::sqrt(0.05 * 0.05 - z * z);
  press(Eigen::Vector3d(r, 0.0003, z), -Eigen::Vector3d::UnitX(), contact, flagged, peak);
  EXPECT_GT(contact, 100);
  EXPECT_GT(flagged, contact / 2);
  EXPECT_LE(peak, scene->haptics.limits.max_force + 1e-9);
  // The top: precomputed, never flagged.
  press(Eigen::Vector3d(0.0005, 0.0003, 0.05), -Eigen::Vector3d::UnitZ(), contact, flagged, peak);
  EXPECT_GT(contact, 100);
  EXPECT_EQ(flagged, 0);
}

}  // namespace
}  // namespace vsurg::sim
