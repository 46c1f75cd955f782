// The deformation pool (common/sim/deformation_pool.h): members stepped when due, never two
// workers on one member, none stepped after Remove returns, none starved; simulations in a pool
// deform exactly as on their own threads, and many of them add no thread.
#include "common/sim/deformation_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "tests/support/wait.h"

namespace vsurg::sim {
namespace {

using Clock = DeformationPool::Clock;

// Counts its steps, due again `period` after each; flags two workers inside it at once.
class Counter final : public DeformationPool::Member {
 public:
  explicit Counter(Clock::duration period) : period_(period) {}
  Clock::time_point StepDue(Clock::time_point now) override {
    if (inside_.exchange(true)) overlapped_ = true;
    steps_.fetch_add(1);
    std::this_thread::sleep_for(std::chrono::microseconds(50));  // some work
    inside_ = false;
    return now + period_;
  }
  uint64_t steps() const { return steps_.load(); }
  bool overlapped() const { return overlapped_.load(); }

 private:
  Clock::duration period_;
  std::atomic<bool> inside_{false}, overlapped_{false};
  std::atomic<uint64_t> steps_{0};
};

int ThreadsOfThisProcess() {
  std::ifstream in("/proc/self/status");
  std::string key;
  int n = 0;
  while (in >> key)
    if (key == "Threads:") in >> n;
  return n;
}

TEST(DeformationPoolTest, EveryMemberIsSteppedByOneWorkerAtATimeAndNotAfterItsRemoval) {
  DeformationPool pool(2);
  EXPECT_EQ(pool.workers(), 2);
  std::vector<std::unique_ptr<Counter>> members;
  for (int i = 0; i < 8; ++i) {
    members.push_back(std::make_unique<Counter>(std::chrono::microseconds(i % 2 ? 0 : 500)));
    pool.Add(members.back().get());
  }
  EXPECT_EQ(pool.members(), 8u);
  // Every member progresses, the always-due ones (period 0) do not starve the others.
  test::Eventually(30, [&] {
    for (const auto& m : members)
      if (m->steps() < 20) return false;
    return true;
  });
  for (const auto& m : members) {
    EXPECT_GE(m->steps(), 20u);
    EXPECT_FALSE(m->overlapped());
  }
  EXPECT_LE(pool.peak_busy(), 2);
  // Once Remove returns, the member is never stepped again (it may be destroyed).
  for (auto& m : members) {
    pool.Remove(m.get());
    const uint64_t at = m->steps();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_EQ(m->steps(), at);
    m.reset();
  }
  EXPECT_EQ(pool.members(), 0u);
  pool.Remove(nullptr);  // not a member: nothing happens
}

// The arm's twist played as fast as possible into two simulations, one on its own deformation
// thread and one in a pool: the coil model follows the newest torque, so once both have caught
// up they show the same surface (within the frames' quantum).
TEST(DeformationPoolTest, ASimulationInAPoolDeformsAsOnItsOwnThread) {
  auto scene = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok());
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  DeformationPool pool(1);
  auto own = Simulation::Create(*scene, {true});
  auto pooled = Simulation::Create(
      *scene, {.threaded = true, .start_deformation = true, .cache_dir = {}, .pool = &pool});
  ASSERT_TRUE(own.ok() && pooled.ok());
  EXPECT_TRUE((*pooled)->deformation_running());
  EXPECT_EQ(pool.members(), 1u);
  const auto& rest = (*own)->rest_mesh().positions;
  std::vector<geometry::Vec3> shown_own(rest), shown_pooled(rest);
  const auto take = [](Simulation& s, std::vector<geometry::Vec3>& shown) {
    VisualFrame f;
    bool any = false;
    while (s.TakeVisualFrame(f)) {
      any = true;
      for (size_t k = 0; k < f.indices.size(); ++k) shown[f.indices[k]] = f.positions[k];
    }
    return any;
  };
  for (const auto& s : *samples) {
    if (s.time > 2.9) break;  // the end of the twist
    (*own)->OnStylus(s);
    (*pooled)->OnStylus(s);
  }
  // Wait until both have deformed (binding the grasp's deformer first: slow in sanitizer
  // builds) and then gone quiet (no new frame for 300 ms), taking what they publish.
  auto quiet = std::chrono::steady_clock::now();
  test::Eventually(120, [&] {
    const bool a = take(**own, shown_own), b = take(**pooled, shown_pooled);
    if (a || b) quiet = std::chrono::steady_clock::now();
    return (*own)->deformation_updates() > 0 && (*pooled)->deformation_updates() > 0 &&
           std::chrono::steady_clock::now() - quiet > std::chrono::milliseconds(300);
  });
  EXPECT_GT((*pooled)->deformation_updates(), 0u);
  double moved = 0, diff = 0;
  for (size_t i = 0; i < rest.size(); ++i) {
    moved = std::max(moved, (shown_pooled[i] - rest[i]).norm());
    diff = std::max(diff, (shown_pooled[i] - shown_own[i]).norm());
  }
  EXPECT_GT(moved, 1e-3);  // the twist moved the wrist end by millimetres
  // Both surfaces are the same; what each shows is its frames', and a frame sends a vertex once
  // it moved 1 µm from where it was last sent: two histories of frames (a loaded machine paces
  // them differently) show it within twice that.
  EXPECT_LT(diff, 2e-6);
  (*pooled)->SetDeformationRunning(false);
  EXPECT_FALSE((*pooled)->deformation_running());
  EXPECT_EQ(pool.members(), 0u);
}

// Sixteen driven sessions of a dynamic (paced) scene on a 2-worker pool: all deform, and the
// process has no more threads than before them; on their own threads it would have sixteen more.
TEST(DeformationPoolTest, ManyPacedSimulationsShareTheWorkersAndAddNoThread) {
  auto scene = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(scene.ok());
  DeformationPool pool(2);
  const int threads_before = ThreadsOfThisProcess();
  std::vector<std::unique_ptr<Simulation>> sims;
  for (int i = 0; i < 16; ++i) {
    auto s = Simulation::Create(
        *scene, {.threaded = true, .start_deformation = true, .cache_dir = {}, .pool = &pool});
    ASSERT_TRUE(s.ok());
    sims.push_back(std::move(*s));
  }
  EXPECT_EQ(ThreadsOfThisProcess(), threads_before);
  EXPECT_EQ(pool.members(), 16u);
  test::Eventually(60, [&] {
    for (const auto& s : sims)
      if (s->deformation_updates() < 10) return false;
    return true;
  });
  for (const auto& s : sims) EXPECT_GE(s->deformation_updates(), 10u);
  sims.clear();  // each leaves the pool as it is destroyed
  EXPECT_EQ(pool.members(), 0u);
}

}  // namespace
}  // namespace vsurg::sim
