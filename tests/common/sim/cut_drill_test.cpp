// The pattern-cutting drill (common/sim/cut_drill.h): the shipped drill files load and bad ones
// are refused by name; an expert hand cuts the circle out within its band and frees the piece, a
// novice's wobble and lifts cost it score; the force while the cut advances is the fracture
// model's J_c t for two tissues; nothing diverges.
#include "common/sim/cut_drill.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "common/sim/scene.h"

namespace vsurg::sim {
namespace {

std::string Drill(const std::string& name) {
  return ScenesDirectory() + "/drills/" + name;
}

TEST(CutDrillTest, TheShippedDrillsLoad) {
  for (const char* name : {"pattern-cut.json", "straight-cut.json"}) {
    auto spec = LoadCutDrill(Drill(name));
    ASSERT_TRUE(spec.ok()) << name << ": " << spec.error().message;
    EXPECT_NEAR(spec->blade.toughness, 1700, 1e-9);
    EXPECT_NEAR(spec->blade.thickness, 1.2e-3, 1e-12);
  }
}

TEST(CutDrillTest, BadDrillsAreRefusedByName) {
  const std::string good = R"({"name": "d", "tissue": {"thickness_mm": 1.2},
    "blade": {"toughness": 1700, "width_mm": 0.3},
    "pattern": {"type": "line", "from_mm": [-20, 0], "to_mm": [20, 0]}, "task": {}})";
  ASSERT_TRUE(ParseCutDrill(good, "good").ok());
  const auto field = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    auto spec = ParseCutDrill(text, "bad");
    return spec.ok() ? std::string("ok") : spec.error().field;
  };
  EXPECT_EQ(field("\"toughness\": 1700", "\"toughness\": 0"), "blade.toughness");
  EXPECT_EQ(field("\"toughness\": 1700", "\"toughness\": -3"), "blade.toughness");
  EXPECT_EQ(field("\"width_mm\": 0.3", "\"width_mm\": 0"), "blade.width_mm");
  EXPECT_EQ(field("\"thickness_mm\": 1.2", "\"thickness_mm\": 0"), "tissue.thickness_mm");
  EXPECT_EQ(field("\"to_mm\": [20, 0]", "\"to_mm\": [60, 0]"), "pattern");
  EXPECT_EQ(field("\"type\": \"line\"", "\"type\": \"zigzag\""), "pattern.type");
  EXPECT_EQ(field("\"name\": \"d\",", ""), "name");
  EXPECT_EQ(ParseCutDrill("{not json", "broken").error().code, ErrorCode::kParseError);
}

TEST(CutDrillTest, AnExpertCutsTheCircleOutWithinItsBandAndANoviceScoresLess) {
  auto spec = LoadCutDrill(Drill("pattern-cut.json"));
  ASSERT_TRUE(spec.ok());
  auto expert = RunCutDrill(*spec, CutHand::Expert(3));
  ASSERT_TRUE(expert.ok());
  EXPECT_FALSE(expert->diverged);
  const scoring::CutMetrics& e = expert->metrics;
  EXPECT_TRUE(e.completed);
  EXPECT_TRUE(e.piece_freed);
  EXPECT_EQ(expert->freed, 1);
  EXPECT_GT(e.coverage, 0.95);
  // The tissue the blade drags along pulls a curved cut a few tenths of a millimetre inside.
  EXPECT_LT(e.deviation_rms, 0.25 * spec->task.pattern.band);
  EXPECT_EQ(e.outside_length, 0.0);
  EXPECT_EQ(e.lifts, 0);
  EXPECT_GE(e.score, 8.5);
  auto novice = RunCutDrill(*spec, CutHand::Novice(3));
  ASSERT_TRUE(novice.ok());
  EXPECT_FALSE(novice->diverged);
  EXPECT_EQ(novice->metrics.lifts, 2);
  EXPECT_GT(novice->metrics.deviation_rms, 1.3 * e.deviation_rms);
  EXPECT_LT(novice->metrics.score, e.score - 1.0);
}

// The goal's check: a scripted straight cut's force, over the steps the cut advances, within 10%
// RMS of J_c t, for the skin of the drill and for a tougher, thinner one.
TEST(CutDrillTest, AStraightCutIsDrawnAtTheFractureModelsForceForItsTissue) {
  auto spec = LoadCutDrill(Drill("straight-cut.json"));
  ASSERT_TRUE(spec.ok());
  for (const auto& [toughness, thickness] :
       {std::pair{1700.0, 1.2e-3}, std::pair{2800.0, 0.8e-3}}) {
    CutDrillSpec s = *spec;
    s.blade.toughness = toughness;
    s.blade.thickness = s.tissue.thickness = thickness;
    auto r = RunCutDrill(s, CutHand::Expert(1));
    ASSERT_TRUE(r.ok());
    EXPECT_NEAR(r->cutting_force, toughness * thickness, 1e-12);
    EXPECT_GT(r->cutting_steps, 5000);
    EXPECT_LT(r->force_rms_error, 0.10) << toughness << " J/m², " << thickness * 1e3 << " mm";
    EXPECT_TRUE(r->metrics.completed);
    EXPECT_NEAR(r->peak_press, r->puncture_force, 0.05 * r->puncture_force)
        << "the press gives way at the fracture criterion";
    EXPECT_FALSE(r->diverged);
  }
}

// The left hand pulling the piece hard away from the cut tears the skin at its jaws: the tear is
// measured apart from the cut, lowers the score, and nothing diverges.
TEST(CutDrillTest, AGraspThatPullsTooHardTearsTheTissue) {
  auto spec = LoadCutDrill(Drill("straight-cut.json"));
  ASSERT_TRUE(spec.ok());
  CutHand gentle = CutHand::Expert(2), rough = CutHand::Expert(2);
  rough.grasp_pull = 0.015;
  auto a = RunCutDrill(*spec, gentle), b = RunCutDrill(*spec, rough);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->metrics.torn_length, 0.0);
  EXPECT_GT(b->metrics.torn_length, 0.0);
  EXPECT_NEAR(b->torn_length, b->metrics.torn_length, 1e-12);
  EXPECT_GT(b->peak_grasp_force, a->peak_grasp_force);
  EXPECT_LT(b->metrics.score, a->metrics.score);
  EXPECT_FALSE(a->diverged || b->diverged);
}

// Proficiency targets from three experts' runs of the straight drill: each expert meets every
// target set from their own runs; the novice misses the deviation and the lifts.
TEST(CutDrillTest, TargetsFromExpertRunsPassTheExpertsAndFailTheNovice) {
  auto spec = LoadCutDrill(Drill("straight-cut.json"));
  ASSERT_TRUE(spec.ok());
  std::vector<scoring::CutMetrics> experts;
  for (uint32_t seed = 1; seed <= 3; ++seed) {
    auto e = RunCutDrill(*spec, CutHand::Expert(seed));
    ASSERT_TRUE(e.ok());
    experts.push_back(e->metrics);
  }
  auto targets = scoring::CutTargetsFromExperts(experts);
  ASSERT_TRUE(targets.ok()) << targets.error().message;
  EXPECT_EQ(targets->size(), 7u);
  for (const auto& e : experts)
    for (const auto& c : scoring::CheckCut(e, *targets)) EXPECT_TRUE(c.met) << c.metric;
  auto novice = RunCutDrill(*spec, CutHand::Novice(1));
  ASSERT_TRUE(novice.ok());
  std::map<std::string, bool> met;
  for (const auto& c : scoring::CheckCut(novice->metrics, *targets)) met[c.metric] = c.met;
  EXPECT_FALSE(met.at("deviation_rms_m"));
  EXPECT_FALSE(met.at("lifts"));
  EXPECT_FALSE(scoring::CutTargetsFromExperts({experts[0]}).ok()) << "one run is no benchmark";
}

}  // namespace
}  // namespace vsurg::sim
