#include "common/sim/simulation.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <random>
#include <thread>

#include <unistd.h>

#include <gtest/gtest.h>

#include "common/sim/trajectory.h"
#include "tests/support/allocation_counter.h"
#include "tests/support/deadline.h"
#include "tests/support/sanitized.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::sim {
namespace {

TEST(SimulationTest, BadSamplesGiveZeroForceAndAnEventThenTheGateRearms) {
  auto scene = LoadSceneByName("sphere-palpation-256");
  auto sim = Simulation::Create(*scene, {false});
  ASSERT_TRUE(sim.ok());
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0.001, 0.001, 0.06);
  for (int i = 0; i < 100; ++i) s.time = i * 1e-3, (*sim)->OnStylus(s);
  s.time = 0.1;
  s.position = Eigen::Vector3d(0.001, 0.001, 0.045);  // inside
  EXPECT_TRUE((*sim)->OnStylus(s).contact);
  s.position.x() = NAN;
  haptics::ForceCommand c = (*sim)->OnStylus(s);
  EXPECT_EQ(c.force, Eigen::Vector3d::Zero());
  EXPECT_TRUE(c.events & haptics::kEventNonFiniteInput);
  EXPECT_TRUE(c.local.jacobian.isZero());
  s.position = Eigen::Vector3d(3.0, 0, 0);
  c = (*sim)->OnStylus(s);
  EXPECT_EQ(c.force, Eigen::Vector3d::Zero());
  EXPECT_TRUE(c.events & haptics::kEventOutOfWorkspace);
  // Back inside the tissue: the gate holds the force at zero (no kick) until it is quiet.
  s.position = Eigen::Vector3d(0.001, 0.001, 0.045);
  c = (*sim)->OnStylus(s);
  EXPECT_TRUE(c.events & haptics::kEventGated);
  EXPECT_EQ(c.force, Eigen::Vector3d::Zero());
}

TEST(SimulationTest, AdversarialStylusInputNeverExceedsTheDeviceLimits) {
  auto scene = LoadSceneByName("arm-torsion");
  auto sim = Simulation::Create(*scene, {false});
  ASSERT_TRUE(sim.ok());
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> pos(-0.1, 0.35), ang(-1, 1), dt(-1e-3, 3e-3);
  std::bernoulli_distribution coin(0.3);
  double t = 0;
  for (int i = 0; i < test::Samples(5000); ++i) {
    haptics::StylusSample s;
    t += dt(rng);
    s.time = i % 1000 == 7 ? NAN : t;
    s.position = Eigen::Vector3d(pos(rng) * 0.3, pos(rng) * 0.3, pos(rng));
    s.orientation = Eigen::Quaterniond(ang(rng), ang(rng), ang(rng), ang(rng));
    if (i % 500 == 3) s.orientation.coeffs().setZero();
    s.buttons = coin(rng) ? haptics::kButtonGrasp : 0u;
    const haptics::ForceCommand c = (*sim)->OnStylus(s);
    (*sim)->StepDeformation();
    ASSERT_TRUE(c.force.allFinite());
    ASSERT_LE(c.force.norm(), 3.3 * (1 + 1e-12));
    ASSERT_TRUE(c.local.jacobian.allFinite());
    ASSERT_EQ(c.local.force0, c.force);
  }
}

// A station clock that jumps (a bad device, a faulty sync, an attacker with the session key) must
// cost bounded work: the trial clock steps at most kMaxClockStepS per sample, the jump is flagged,
// and the trial's duration grows by no more than that bound per jump.
TEST(SimulationTest, AStationClockJumpIsBoundedAndFlagged) {
  for (const char* name : {"arm-torsion", "sphere-palpation-256"}) {
    SCOPED_TRACE(name);
    auto scene = LoadSceneByName(name);
    ASSERT_TRUE(scene.ok());
    test::ReturnsWithin(30, "OnStylus after a clock jump", [&] {
      auto sim = Simulation::Create(*scene, {false});
      ASSERT_TRUE(sim.ok());
      std::vector<haptics::StylusSample> samples;
      haptics::StylusSample s;
      s.position = Eigen::Vector3d(0.001, 0.001, 0.3);
      for (int i = 0; i < 100; ++i) s.time = i * 1e-3, samples.push_back(s);
      for (double t : {1e7, 1e308, 1.5e308, -5.0, -4.999}) s.time = t, samples.push_back(s);
      uint32_t flagged = 0;
      (*sim)->Replay(samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
        if (c.events & haptics::kEventClockJump) ++flagged;
        ASSERT_TRUE(c.force.allFinite());
      });
      // 1e7, 1e308, 1.5e308 (forward) and −5.0 (backwards) jumped; −4.999 is a 1 ms step.
      EXPECT_EQ((*sim)->clock_jumps(), 4u);
      EXPECT_EQ(flagged, 4u);
      const scoring::TrialMetrics m = (*sim)->Metrics();
      // 99 ms of samples, three jumps forward of at most 1 s, one back of 1 ms, then 1 ms.
      EXPECT_LE(m.duration, 0.099 + 3 * kMaxClockStepS + 2e-3 + 1e-9);
      EXPECT_GE(m.duration, 0.099 + 3 * kMaxClockStepS);
      EXPECT_NEAR((*sim)->trial_time(), m.duration, 1e-9);
    });
  }
}

TEST(SimulationTest, ThreadedDeformationPublishesOnlyMovedVertices) {
  auto scene = LoadSceneByName("arm-torsion");
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  auto sim = Simulation::Create(*scene, {true});
  ASSERT_TRUE(sim.ok());
  VisualFrame frame;
  // Play up to the end of the twist (t ≈ 2.9 s), as fast as we can.
  for (const auto& s : *samples) {
    if (s.time > 2.9) break;
    (*sim)->OnStylus(s);
  }
  // The deformation thread binds a deformer at the grasp, then follows the newest torque; wait
  // (generously: sanitizer builds are slow) for a frame with the twist in it.
  ASSERT_TRUE(test::Eventually(
      30, [&] { return (*sim)->TakeVisualFrame(frame) && !frame.indices.empty(); },
      std::chrono::milliseconds(2)));
  ASSERT_GT((*sim)->deformation_updates(), 0u);
  EXPECT_LT(frame.indices.size(), (*sim)->rest_mesh().positions.size());  // the elbow end stays
  const auto& rest = (*sim)->rest_mesh().positions;
  for (size_t k = 0; k < frame.indices.size(); ++k) {
    const auto& p0 = rest[frame.indices[k]];
    EXPECT_GT((frame.positions[k] - p0).norm(), 1e-6);
    EXPECT_NEAR(std::hypot(frame.positions[k].x(), frame.positions[k].y()),
                std::hypot(p0.x(), p0.y()), 1e-9);
  }
  // Once the thread has caught up with the last torque, nothing new moves: no frame, or an empty
  // one.
  VisualFrame again;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  auto quiet_since = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - quiet_since < std::chrono::milliseconds(300) &&
         std::chrono::steady_clock::now() < deadline) {
    if ((*sim)->TakeVisualFrame(again) && !again.indices.empty())
      quiet_since = std::chrono::steady_clock::now();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_FALSE((*sim)->TakeVisualFrame(again) && !again.indices.empty());
}

// A quasi-static model (the arm's coil) updates on a new request, at most once per interval, from
// the newest request. A hand twists at 1 kHz (the good trainee's grasp samples up to the twist's
// end, one a millisecond in real time), which asks for an update at most samples: the updates stay
// within one per interval, and once the hand stops, the surface is the one the last request gives
// (a replay that updates once, after the same samples). A slower machine only makes fewer updates.
// On a thread of its own and as a member of a deformation pool alike.
void UpdatesAtMostOncePerIntervalFromTheNewestRequest(DeformationPool* pool) {
  auto scene = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok());
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  constexpr double kInterval = 0.02;  // s
  auto sim = Simulation::Create(
      *scene, {.threaded = true, .pool = pool, .quasi_static_interval_s = kInterval});
  auto reference = Simulation::Create(*scene, {.threaded = false});
  ASSERT_TRUE(sim.ok() && reference.ok());
  using Clock = std::chrono::steady_clock;
  Clock::time_point paced_from{};
  uint64_t updates_before = 0, requests_before = 0;
  int paced = 0;
  for (const auto& s : *samples) {
    if (s.time > 1.9) break;  // mid-twist (0.9–2.9 s), where the hand turns fastest
    const bool grasp = (*sim)->OnStylus(s).grasping;
    (*reference)->OnStylus(s);
    if (!grasp) continue;
    if (paced == 0) {
      paced_from = Clock::now();
      updates_before = (*sim)->deformation_updates();
      requests_before = (*sim)->deformation_requests();
    }
    std::this_thread::sleep_until(paced_from + std::chrono::milliseconds(++paced));
  }
  const double elapsed = std::chrono::duration<double>(Clock::now() - paced_from).count();
  const uint64_t updates = (*sim)->deformation_updates() - updates_before;
  ASSERT_GT(paced, 500);
  EXPECT_GT((*sim)->deformation_requests() - requests_before, static_cast<uint64_t>(paced / 4))
      << "the twist asks, in " << paced << " samples";
  EXPECT_LE(updates, static_cast<uint64_t>(elapsed / kInterval) + 2)
      << "in " << elapsed << " s with one update per " << kInterval << " s at most";
  // The newest request is served: the surface ends as the reference's after one update.
  (*reference)->StepDeformation();
  const auto surface = [](Simulation& sm, std::vector<geometry::Vec3>& x) {
    VisualFrame f;
    while (sm.TakeVisualFrame(f))
      for (size_t k = 0; k < f.indices.size(); ++k) x[f.indices[k]] = f.positions[k];
  };
  std::vector<geometry::Vec3> expected = (*reference)->rest_mesh().positions;
  surface(**reference, expected);
  std::vector<geometry::Vec3> shown = (*sim)->rest_mesh().positions;
  const auto farthest = [&] {
    double d = 0;
    for (size_t i = 0; i < shown.size(); ++i) d = std::max(d, (shown[i] - expected[i]).norm());
    return d;
  };
  const auto deadline = Clock::now() + std::chrono::seconds(30);
  double off = 0;
  // Within 2 µm: frames carry the vertices that moved more than 1 µm, and the coil's update
  // depends on the one before by some 0.1 µm; an update 20 ms older is some 100 µm off.
  do {
    surface(**sim, shown);
    off = farthest();
    if (off > 2e-6) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  } while (off > 2e-6 && Clock::now() < deadline);
  EXPECT_LE(off, 2e-6) << "m from the newest request's surface";
  double twisted = 0;  // the reference's largest move from rest: the twist is in the surface
  for (size_t i = 0; i < expected.size(); ++i)
    twisted = std::max(twisted, (expected[i] - (*sim)->rest_mesh().positions[i]).norm());
  EXPECT_GT(twisted, 1e-4) << "m";
}

TEST(SimulationTest, AQuasiStaticModelUpdatesAtMostOncePerIntervalFromTheNewestRequest) {
  {
    SCOPED_TRACE("a thread of its own");
    UpdatesAtMostOncePerIntervalFromTheNewestRequest(nullptr);
  }
  SCOPED_TRACE("a pool's member");
  DeformationPool pool(1);
  UpdatesAtMostOncePerIntervalFromTheNewestRequest(&pool);
}

// The haptic path wakes the deformation only for what the scene's model reads. A twist model (the
// arm's coil) reads the grasp and its torque, so a touch that does not grasp asks nothing of it,
// while its grasp's twist does; a press on the sphere (a mass-spring, which a press deforms)
// asks for an update at every sample in which the press changed (a quarter of them in this
// trial: it holds its depth for long).
TEST(SimulationTest, OnlyWhatTheModelReadsWakesItsDeformation) {
  for (const char* name : {"arm-torsion", "sphere-palpation-256"}) {
    SCOPED_TRACE(name);
    auto scene = LoadSceneByName(name);
    ASSERT_TRUE(scene.ok());
    auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
    ASSERT_TRUE(samples.ok());
    auto sim = Simulation::Create(*scene, {false});
    ASSERT_TRUE(sim.ok()) << sim.error().message;
    int press_samples = 0, grasp_samples = 0;
    uint64_t press_requests = 0, grasp_requests = 0;
    for (const auto& s : *samples) {
      const uint64_t before = (*sim)->deformation_requests();
      const haptics::ForceCommand c = (*sim)->OnStylus(s);
      const uint64_t asked = (*sim)->deformation_requests() - before;
      if (c.grasping) {
        ++grasp_samples;
        grasp_requests += asked;
      } else if (c.contact) {
        ++press_samples;
        press_requests += asked;
      }
    }
    ASSERT_GT(press_samples, 200);
    if (std::string(name) == "arm-torsion") {
      // All a touch may ask: the grasp's release, seen while the tool still touches.
      EXPECT_LE(press_requests, 2u) << "of " << press_samples << " samples touching the arm";
      ASSERT_GT(grasp_samples, 200);
      EXPECT_GT(grasp_requests, static_cast<uint64_t>(grasp_samples / 4)) << "the twist asks";
    } else {
      EXPECT_GT(press_requests, static_cast<uint64_t>(press_samples / 8))
          << "of " << press_samples << " samples pressing the sphere";
    }
  }
}

TEST(SimulationTest, TheHapticPathNeverAllocates) {
  if (!test::CanCountAllocations())
    GTEST_SKIP() << "operator new cannot be replaced under ThreadSanitizer";
  // The counter sees an allocation when there is one.
  test::ResetAllocations();
  test::CountThisThread(true);
  static std::vector<double>* volatile probe = nullptr;  // escapes: the allocation cannot be elided
  probe = new std::vector<double>(100);
  test::CountThisThread(false);
  delete probe;
  ASSERT_GE(test::Allocations(), 2);
  for (const char* name :
       {"arm-torsion", "sphere-palpation-256", "sphere-palpation-rings", "organ-surface-twist"}) {
    auto scene = LoadSceneByName(name);
    auto samples = ScriptedTrainee(*scene, TraineeStyle::kRough);
    auto sim = Simulation::Create(*scene, {true});
    ASSERT_TRUE(sim.ok());
    haptics::StylusSample bad;
    bad.position.x() = NAN;
    test::ResetAllocations();
    test::CountThisThread(true);
    for (const auto& s : *samples) (*sim)->OnStylus(s);
    (*sim)->OnStylus(bad);
    test::CountThisThread(false);
    EXPECT_EQ(test::Allocations(), 0) << name;
  }
}

TEST(TripleBufferTest, ReaderAlwaysSeesACompleteNewerValue) {
  struct Value {
    uint64_t n = 0;
    uint64_t twice = 0;
    std::array<uint64_t, 64> pad{};
  };
  TripleBuffer<Value> buffer;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (uint64_t n = 1; n <= 300000; ++n) {
      Value& v = buffer.Back();
      v.n = n;
      v.pad.fill(n);
      v.twice = 2 * n;
      buffer.Publish();
    }
    done = true;
  });
  uint64_t last = 0, seen = 0;
  while (!done || buffer.Acquire()) {
    if (!buffer.Acquire() && !done) continue;
    const Value& v = buffer.Front();
    ASSERT_EQ(v.twice, 2 * v.n);
    ASSERT_EQ(v.pad[63], v.n);
    ASSERT_GE(v.n, last);
    last = v.n;
    ++seen;
  }
  writer.join();
  buffer.Acquire();
  EXPECT_EQ(buffer.Front().n, 300000u);
  EXPECT_GT(seen, 0u);
}

}  // namespace
}  // namespace vsurg::sim
