// A needle scene end to end in one process: scenes/needle-vessel.json's layers and vein, the
// scripted trainees through Simulation's haptic path, the metrics and the score; the needle's
// state in the answers and across a live migration.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include "common/sim/needle_trainee.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {
namespace {

Scene NeedleScene() {
  auto scene = LoadScene(ScenesDirectory() + "/needle-vessel.json");
  EXPECT_TRUE(scene.ok()) << (scene.ok() ? "" : scene.error().message);
  return *scene;
}

struct Played {
  scoring::TrialMetrics metrics;
  int pops = 0, marks = 0, back_walls = 0, needle_answers = 0;
  double peak_force = 0;
};

Played Play(const Scene& scene, TraineeStyle style) {
  auto plan = NeedleTrainee(scene, style);
  EXPECT_TRUE(plan.ok());
  auto sim = Simulation::Create(scene, {.threaded = false});
  EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
  Played p;
  (*sim)->Replay(*plan, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    p.pops += (c.events & haptics::kEventPunctured) != 0;
    p.marks += (c.events & haptics::kEventMarked) != 0;
    p.back_walls += (c.events & haptics::kEventBackWall) != 0;
    p.needle_answers += c.local.kind == haptics::LocalModel::Kind::kNeedle;
    p.peak_force = std::max(p.peak_force, c.force.norm());
  });
  p.metrics = (*sim)->Metrics();
  return p;
}

TEST(NeedleSessionTest, AGoodInsertionPuncturesFourBoundariesAndIsConfirmedInTheVein) {
  const Scene scene = NeedleScene();
  const Played p = Play(scene, TraineeStyle::kGood);
  // Skin, fat, muscle's fascia, the vein's front wall.
  EXPECT_EQ(p.pops, 4);
  EXPECT_EQ(p.metrics.punctures, 4);
  EXPECT_EQ(p.metrics.extra_punctures, 0);
  EXPECT_EQ(p.metrics.back_wall_breaches, 0);
  EXPECT_EQ(p.marks, 1);
  EXPECT_TRUE(p.metrics.completed);
  EXPECT_LT(p.metrics.depth_error, 1e-3);
  EXPECT_LT(p.metrics.path_deviation, 1e-4);
  EXPECT_LT(p.metrics.lateral_strain, 0.01);
  EXPECT_GT(p.peak_force, 1.0);  // the skin's 1.5 N before it gave way
  EXPECT_LE(p.peak_force, scene.task.force_limit);
  EXPECT_GT(p.needle_answers, 0);
  EXPECT_GT(p.metrics.score, 8.0);
}

TEST(NeedleSessionTest, AHesitantInsertionMissesFirstAndPaysForItsSecondPath) {
  const Played p = Play(NeedleScene(), TraineeStyle::kHesitant);
  EXPECT_TRUE(p.metrics.completed);
  EXPECT_EQ(p.metrics.back_wall_breaches, 0);
  EXPECT_GE(p.metrics.extra_punctures, 3);  // the first path's skin, fat and muscle
  EXPECT_EQ(p.marks, 1);                    // the early confirmation did not count
  const Played good = Play(NeedleScene(), TraineeStyle::kGood);
  EXPECT_LT(p.metrics.score, good.metrics.score - 1.0);
}

TEST(NeedleSessionTest, ARoughInsertionThroughTheBackWallIsCappedAtThree) {
  const Played p = Play(NeedleScene(), TraineeStyle::kRough);
  EXPECT_EQ(p.metrics.back_wall_breaches, 1);
  EXPECT_EQ(p.back_walls, 1);
  EXPECT_TRUE(p.metrics.caps & scoring::kCapBackWall);
  EXPECT_LE(p.metrics.score, 3.0);
  EXPECT_GT(p.metrics.lateral_strain, 0.05);  // levered sideways
}

TEST(NeedleSessionTest, ACystIsReachedLikeAVeinThroughItsOwnLayers) {
  auto scene = LoadScene(ScenesDirectory() + "/needle-cyst.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  ASSERT_EQ(scene->needle->target.kind, haptics::NeedleTarget::Kind::kCyst);
  const Played good = Play(*scene, TraineeStyle::kGood);
  EXPECT_EQ(good.metrics.punctures, 4);  // skin, fat, the glandular tissue's top, the cyst's wall
  EXPECT_TRUE(good.metrics.completed);
  EXPECT_LT(good.metrics.depth_error, 1e-3);
  const Played rough = Play(*scene, TraineeStyle::kRough);
  EXPECT_EQ(rough.metrics.back_wall_breaches, 1);
  EXPECT_LE(rough.metrics.score, 3.0);
}

TEST(NeedleSessionTest, AMigratedSessionGoesOnFromTheSameTractAndPunctures) {
  const Scene scene = NeedleScene();
  auto plan = NeedleTrainee(scene, TraineeStyle::kGood);
  ASSERT_TRUE(plan.ok());
  auto a = Simulation::Create(scene, {.threaded = false});
  auto b = Simulation::Create(scene, {.threaded = false});
  ASSERT_TRUE(a.ok() && b.ok());
  // Halfway down: through the skin and the fat, in the muscle.
  const size_t half = plan->size() / 2;
  std::vector<haptics::StylusSample> first(plan->begin(), plan->begin() + half),
      rest(plan->begin() + half, plan->end());
  (*a)->Replay(first, [](const auto&, const auto&) {});
  ASSERT_EQ((*a)->needle()->state().phase, haptics::NeedleState::Phase::kInserted);
  const std::string bytes = (*a)->SaveState();
  ASSERT_TRUE((*b)->RestoreState(bytes).ok());
  EXPECT_EQ((*b)->needle()->state(), (*a)->needle()->state());
  EXPECT_EQ((*b)->needle()->punctures(), (*a)->needle()->punctures());
  std::vector<haptics::ForceCommand> from_a, from_b;
  (*a)->Replay(rest, [&](const auto&, const haptics::ForceCommand& c) { from_a.push_back(c); });
  (*b)->Replay(rest, [&](const auto&, const haptics::ForceCommand& c) { from_b.push_back(c); });
  ASSERT_EQ(from_a.size(), from_b.size());
  for (size_t i = 0; i < from_a.size(); ++i) ASSERT_EQ(from_a[i].force, from_b[i].force) << i;
  EXPECT_EQ((*b)->Metrics().punctures, 4);
}

TEST(NeedleSessionTest, ANeedleSceneOutOfRangeIsRefusedByName) {
  auto text = [](const std::string& edit_from, const std::string& edit_to) {
    std::ifstream in(ScenesDirectory() + "/needle-vessel.json");
    std::stringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    const size_t at = s.find(edit_from);
    EXPECT_NE(at, std::string::npos) << edit_from;
    return s.replace(at, edit_from.size(), edit_to);
  };
  auto bad = ParseScene(text("\"puncture_n\": 1.5", "\"puncture_n\": 0"), "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().field, "needle.layers[0].puncture_n");
  bad = ParseScene(text("\"friction_sliding\": 4,", "\"friction_sliding\": 9,"), "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().field, "needle.layers[1].friction_sliding");
  bad = ParseScene(text("\"depth_mm\": 22", "\"depth_mm\": 4"), "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().field, "needle.target.depth_mm");
  bad = ParseScene(text("\"type\": \"insert\"",
                        "\"type\": \"press\", \"target_depth_m\": 0.01, "
                        "\"tolerance_m\": 0.002"),
                   "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().field, "task.type");
}

}  // namespace
}  // namespace vsurg::sim
