// What the room tests share: a scene's scripted trainee replayed through a whole Simulation, and
// the palpation check every contact room passes.
#pragma once

#include <algorithm>
#include <string>

#include <gtest/gtest.h>

#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim::rooms_test {

// The trial metrics of `scene_name`'s scripted trainee of `style`, replayed without threads; the
// largest force commanded in `peak` when given.
inline scoring::TrialMetrics Replay(const std::string& scene_name, TraineeStyle style,
                                    double* peak = nullptr) {
  auto scene = LoadSceneByName(scene_name);
  EXPECT_TRUE(scene.ok());
  auto samples = ScriptedTrainee(*scene, style);
  EXPECT_TRUE(samples.ok());
  auto sim = Simulation::Create(*scene, {false});
  EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
  double max_force = 0;
  (*sim)->Replay(*samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    max_force = std::max(max_force, c.force.norm());
  });
  if (peak) *peak = max_force;
  return (*sim)->Metrics();
}

// A good scripted trainee presses the scene's target depth within 1 mm and feels the tissue push
// back; a rough one scores at least 3 points lower.
inline void ExpectPalpatedByScriptedTrainees(const std::string& scene) {
  SCOPED_TRACE(scene);
  const scoring::TrialMetrics good = Replay(scene, TraineeStyle::kGood);
  ASSERT_TRUE(good.completed);
  EXPECT_LT(good.task_error, 0.001);
  EXPECT_GT(good.peak_force, 0.02);  // the tissue pushes back
  EXPECT_GE(good.score, 8.0);
  const scoring::TrialMetrics rough = Replay(scene, TraineeStyle::kRough);
  EXPECT_LT(rough.score, good.score - 3.0);
}

}  // namespace vsurg::sim::rooms_test
