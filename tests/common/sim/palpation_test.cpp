// Palpation: a scripted examiner searches a pad for hidden lumps through a whole Simulation,
// closed on the forces it feels (common/sim/palpation_search.h), and the trial's palpation
// metrics (common/scoring/palpation.h) say what it found; the cases a scene draws
// (common/sim/palpation_case.h).
#include <cstdio>

#include <gtest/gtest.h>

#include "common/sim/palpation_case.h"
#include "common/sim/palpation_search.h"
#include "common/sim/simulation.h"
#include "tests/support/temp_dir.h"

namespace vsurg::sim {
namespace {

struct Searched {
  scoring::TrialMetrics metrics;
  size_t spots = 0;
  double max_excess = 0;
};

// `scene` searched by a hand of `style` from start to end, the deformation stepped after every
// fourth sample (the reduced contact is quasi-static: it follows the newest input).
Searched Search(const Scene& scene, const SearchStyle& style, const std::string& cache) {
  auto sim = Simulation::Create(scene, {.threaded = false, .cache_dir = cache});
  EXPECT_TRUE(sim.ok()) << (sim.ok() ? "" : sim.error().message);
  if (!sim.ok()) return {};
  auto search = PalpationSearch::Create((*sim)->rest_mesh(), (*sim)->held_vertices(), style);
  EXPECT_TRUE(search.ok());
  SearchThrough(**sim, *search, [](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    EXPECT_TRUE(c.force.allFinite());
  });
  EXPECT_TRUE(search->done());
  Searched out{(*sim)->Metrics(), search->spots().size(), 0};
  for (double e : search->excess()) out.max_excess = std::max(out.max_excess, e);
  const scoring::TrialMetrics& m = out.metrics;
  std::printf(
      "%s: %zu spots in %.0f s, largest excess %.3f; found %d of %d, %d false, %.1f mm "
      "off, %.0f%% covered, mean force %.2f N, score %.1f\n",
      scene.name.c_str(), out.spots, m.duration, out.max_excess, m.lumps_found, m.lumps,
      m.false_marks, 1e3 * m.localisation_error, 100 * m.coverage, m.mean_force, m.score);
  return out;
}

Scene PadWith(const std::vector<tissue::Inclusion>& lumps, const std::string& name) {
  auto scene = LoadSceneByName("lump-search");
  EXPECT_TRUE(scene.ok()) << (scene.ok() ? "" : scene.error().message);
  Scene s = *scene;
  s.cases.reset();
  s.inclusions = lumps;
  s.name = name;
  return s;
}

// The goal's lump: 10 mm across, five times as stiff, its centre 15 mm under the pad's top.
const tissue::Inclusion kLump{{0.013, -0.009, 0.025}, 0.005, 5};

TEST(PalpationTest, AnExpertFindsATenMillimetreLumpFifteenMillimetresDeepANoviceMissesIt) {
  const test::TempDir dir("palpation");
  const Searched expert = Search(PadWith({kLump}, "one-lump"), ExpertSearch(), dir.string());
  EXPECT_EQ(expert.metrics.lumps, 1);
  EXPECT_EQ(expert.metrics.lumps_found, 1);
  EXPECT_EQ(expert.metrics.false_marks, 0);
  EXPECT_LT(expert.metrics.localisation_error, 0.005);
  EXPECT_GT(expert.metrics.coverage, 0.9);
  EXPECT_TRUE(expert.metrics.completed);
  EXPECT_LT(expert.metrics.peak_force, 3.0);
  const Searched novice = Search(PadWith({kLump}, "one-lump"), NoviceSearch(), dir.string());
  EXPECT_EQ(novice.metrics.lumps_found, 0);
  EXPECT_LT(novice.metrics.coverage, 0.5);
  EXPECT_LT(novice.metrics.score, expert.metrics.score - 3);
}

// The scripted trainees every exercise has, on the goal's lump: the good one (the expert) finds
// it; the hesitant one, as dense but light and slow, takes longer with less force; the rough one
// presses past the force limit and marks what is not there. The score ranks them.
TEST(PalpationTest, TheGoodHesitantAndRoughSearchesScoreApart) {
  const test::TempDir dir("palpation_styles");
  const Scene pad = PadWith({kLump}, "one-lump");
  const Searched good = Search(pad, *SearchStyleByName("good", "style"), dir.string());
  const Searched hesitant = Search(pad, *SearchStyleByName("hesitant", "style"), dir.string());
  const Searched rough = Search(pad, *SearchStyleByName("rough", "style"), dir.string());
  EXPECT_EQ(good.metrics.lumps_found, 1);
  EXPECT_GT(hesitant.metrics.duration, 1.5 * good.metrics.duration);
  EXPECT_LT(hesitant.metrics.peak_force, good.metrics.peak_force);
  EXPECT_GT(rough.metrics.peak_force, pad.task.force_limit);
  EXPECT_GT(rough.metrics.false_marks, 0);
  EXPECT_GT(good.metrics.score, hesitant.metrics.score + 1);
  EXPECT_GT(good.metrics.score, rough.metrics.score + 1);
  EXPECT_FALSE(SearchStyleByName("gentle", "style").ok());
}

// With no lump the healthy pad's smooth trend leaves nothing to mark: the largest excess is a
// tenth of the threshold, and no mark is made.
TEST(PalpationTest, AnExpertMarksNothingInAPadWithoutALump) {
  const test::TempDir dir("palpation");
  const Searched expert = Search(PadWith({}, "lump-free"), ExpertSearch(), dir.string());
  EXPECT_EQ(expert.metrics.lumps, 0);
  EXPECT_EQ(expert.metrics.false_marks, 0);
  EXPECT_LT(expert.max_excess, ExpertSearch().threshold / 3);
  EXPECT_GT(expert.metrics.score, 9);
}

// Cases drawn per seed: each the same for its seed, named apart, its lumps away from the rim; over
// the first two seeds whose case hides a lump (a third of the cases hide none), the metrics tell
// the expert from the novice: at least as many lumps found, no more false marks, marks nearer the
// lumps, more of the pad examined, and a score two points higher in each case.
TEST(PalpationTest, DrawnCasesSeparateTheExpertFromTheNovice) {
  const test::TempDir dir("palpation_cases");
  auto scene = LoadSceneByName("lump-search");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  int expert_found = 0, novice_found = 0, lumps = 0, expert_false = 0, novice_false = 0;
  int searched = 0;
  for (uint64_t seed = 1; seed < 40 && searched < 2; ++seed) {
    auto drawn = DrawCase(*scene, seed);
    ASSERT_TRUE(drawn.ok()) << drawn.error().message;
    if (drawn->inclusions.empty()) continue;
    ++searched;
    auto again = DrawCase(*scene, seed);
    ASSERT_TRUE(again.ok());
    ASSERT_EQ(drawn->inclusions.size(), again->inclusions.size());
    for (size_t k = 0; k < drawn->inclusions.size(); ++k) {
      const tissue::Inclusion& lump = drawn->inclusions[k];
      EXPECT_EQ(lump.centre, again->inclusions[k].centre);
      EXPECT_LE(std::abs(lump.centre.x()), 0.06 - 0.025 + 1e-9);
      EXPECT_LE(std::abs(lump.centre.y()), 0.06 - 0.025 + 1e-9);
    }
    EXPECT_EQ(drawn->name, CaseName("lump-search", seed));
    const Searched expert = Search(*drawn, ExpertSearch(), dir.string());
    const Searched novice = Search(*drawn, NoviceSearch(), dir.string());
    EXPECT_GT(expert.metrics.score, novice.metrics.score + 2);
    EXPECT_GT(expert.metrics.coverage, novice.metrics.coverage + 0.5);
    if (novice.metrics.lumps_found > 0) {
      EXPECT_LT(expert.metrics.localisation_error, novice.metrics.localisation_error);
    }
    lumps += expert.metrics.lumps;
    expert_found += expert.metrics.lumps_found;
    novice_found += novice.metrics.lumps_found;
    expert_false += expert.metrics.false_marks;
    novice_false += novice.metrics.false_marks;
  }
  std::printf("over two cases: %d lumps; the expert found %d (%d false), the novice %d (%d)\n",
              lumps, expert_found, expert_false, novice_found, novice_false);
  EXPECT_EQ(expert_found, lumps);
  EXPECT_EQ(expert_false, 0);
  EXPECT_GE(expert_found, novice_found);
  EXPECT_LE(expert_false, novice_false);
}

// Hard cases on the coarsest pad (10 mm cells): a lump that reaches the surface, stiff and
// shallow, is found and every force stays finite; a "lump" of contrast 1 is no lump at all.
Scene CoarsePad(const std::vector<tissue::Inclusion>& lumps, const std::string& name) {
  auto scene = ParseScene(R"({"name": "coarse-pad",
      "mesh": {"type": "block", "size": [0.1, 0.1, 0.03], "cells": [10, 10, 3]},
      "tissue": {"shear_modulus": 1100, "poisson_ratio": 0.47},
      "regions": [{"name": "r", "model": {"type": "reduced", "mode": "contact",
                   "footprint_radius": 0.009, "support": {"plane": {"point": [0, 0, 0.001],
                   "normal": [0, 0, 1]}}}}],
      "task": {"type": "palpate", "time_limit_s": 300},
      "error_budget": {"rms": 0.2}})",
                          "coarse-pad.json");
  EXPECT_TRUE(scene.ok()) << scene.error().message;
  Scene s = *scene;
  s.inclusions = lumps;
  s.name = name;
  return s;
}

TEST(PalpationTest, OnTheCoarsestPadALumpAtTheSurfaceIsFoundAndAContrastOfOneIsNone) {
  const test::TempDir dir("palpation_hard");
  const Searched surface = Search(CoarsePad({{{0.004, 0.002, 0.027}, 0.006, 10}}, "surface-lump"),
                                  ExpertSearch(), dir.string());
  EXPECT_EQ(surface.metrics.lumps, 1);
  EXPECT_EQ(surface.metrics.lumps_found, 1);
  EXPECT_EQ(surface.metrics.false_marks, 0);
  EXPECT_LT(surface.metrics.peak_force, 3.3);  // the device's limit
  const Searched none = Search(CoarsePad({{{0.004, 0.002, 0.015}, 0.006, 1}}, "contrast-one"),
                               ExpertSearch(), dir.string());
  EXPECT_EQ(none.metrics.lumps, 0);
  EXPECT_EQ(none.metrics.false_marks, 0);
}

}  // namespace
}  // namespace vsurg::sim
