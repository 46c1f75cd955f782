// The bank of palpation cases (common/sim/case_bank.h): cases built ahead in the cache, taken one
// per attempt, each a different draw, the taken case's table file removed once loaded.
#include "common/sim/case_bank.h"

#include <filesystem>
#include <set>

#include <gtest/gtest.h>

#include "common/sim/palpation_case.h"
#include "common/sim/simulation.h"
#include "tests/support/temp_dir.h"

namespace vsurg::sim {
namespace {

namespace fs = std::filesystem;

// A small pad (6 × 6 × 3 cm, 10 × 10 × 5 cells) whose cases build in a fraction of a second.
Scene SmallPad() {
  auto scene = ParseScene(R"({"name": "small-pad",
      "mesh": {"type": "block", "size": [0.06, 0.06, 0.03], "cells": [10, 10, 5]},
      "tissue": {"shear_modulus": 1100, "poisson_ratio": 0.45},
      "regions": [{"name": "r", "model": {"type": "reduced", "mode": "contact",
                   "footprint_radius": 0.009, "support": {"plane": {"point": [0, 0, 0.001],
                   "normal": [0, 0, 1]}}}}],
      "task": {"type": "palpate", "cases": {"count": [1, 1], "depth_mm": [5, 12],
               "diameter_mm": [8, 10], "margin_mm": 10}},
      "error_budget": {"rms": 0.2}})",
                          "small-pad.json");
  EXPECT_TRUE(scene.ok()) << scene.error().message;
  return *scene;
}

TEST(CaseBankTest, CasesAreBuiltAheadTakenOnceAndTheirFilesRemovedWhenDone) {
  const test::TempDir dir("case_bank");
  const Scene pad = SmallPad();
  CaseBank bank({dir.string(), 2});
  bank.Keep(pad);
  ASSERT_TRUE(bank.WaitReady(120)) << "two cases not built in 120 s";
  CaseBank::Stats s = bank.stats();
  EXPECT_EQ(s.ready, 2u);
  EXPECT_GE(s.built, 2u);
  EXPECT_GT(s.mean_build_s, 0);
  std::set<uint64_t> seeds;
  for (int k = 0; k < 2; ++k) {
    auto seed = bank.Take(pad);
    ASSERT_TRUE(seed.has_value());
    EXPECT_TRUE(seeds.insert(*seed).second) << "the same case twice";
    const fs::path file = dir.path() / (CaseName(pad.name, *seed) + "-contact.vrm");
    EXPECT_TRUE(fs::exists(file)) << "the case's table is built ahead";
    // The session builds from the cached table, then the file is done with.
    auto drawn = DrawCase(pad, *seed);
    ASSERT_TRUE(drawn.ok());
    ASSERT_EQ(drawn->inclusions.size(), 1u);
    auto sim = Simulation::Create(*drawn, {.threaded = false, .cache_dir = dir.string()});
    ASSERT_TRUE(sim.ok()) << sim.error().message;
    EXPECT_EQ((*sim)->palpation().lumps().size(), 1u);
    bank.Discard(pad.name, *seed);
    EXPECT_FALSE(fs::exists(file));
  }
  EXPECT_EQ(bank.stats().taken, 2u);
  // Taken dry, the bank says so (the caller builds its own) and builds more.
  std::optional<uint64_t> none;
  for (int k = 0; k < 3 && (none = bank.Take(pad)); ++k) {
  }
  EXPECT_FALSE(none.has_value());
  EXPECT_GE(bank.stats().missed, 1u);
  EXPECT_TRUE(bank.WaitReady(120));
}

// A bank started on a cache that holds cases (an earlier process's) takes them as ready without
// building, and removes the ones beyond its size; a bank that keeps none leaves them alone.
TEST(CaseBankTest, ABankAdoptsTheCasesAnEarlierProcessLeftAndRemovesTheSurplus) {
  const test::TempDir dir("case_bank_adopt");
  const Scene pad = SmallPad();
  {
    CaseBank first({dir.string(), 3});
    first.Keep(pad);
    ASSERT_TRUE(first.WaitReady(120));
  }
  const auto files = [&] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir.path()))
      n += e.path().filename().string().rfind("small-pad.case-", 0) == 0;
    return n;
  };
  ASSERT_GE(files(), 3);
  {
    CaseBank none({dir.string(), 0});
    none.Keep(pad);
    EXPECT_GE(files(), 3) << "a bank that keeps none removes nothing";
  }
  CaseBank second({dir.string(), 2});
  second.Keep(pad);
  EXPECT_EQ(second.stats().ready, 2u) << "adopted at once";
  EXPECT_EQ(second.stats().built, 0u);
  EXPECT_EQ(files(), 2) << "the surplus is removed";
  auto seed = second.Take(pad);
  ASSERT_TRUE(seed.has_value());
  EXPECT_TRUE(fs::exists(dir.path() / (CaseName(pad.name, *seed) + "-contact.vrm")));
}

TEST(CaseBankTest, ASceneWithoutCasesIsNotKeptAndTheBankStopsMidBuild) {
  const test::TempDir dir("case_bank_stop");
  Scene plain = SmallPad();
  plain.cases.reset();
  {
    CaseBank bank({dir.string(), 2});
    EXPECT_FALSE(bank.Take(plain).has_value());
    EXPECT_EQ(bank.stats().missed, 0u);  // not a scene that draws cases: nothing was asked
    bank.Keep(SmallPad());
  }  // destroyed while it builds: it finishes the case in hand and stops
  EXPECT_NE(CaseBank::NewSeed(), CaseBank::NewSeed());
}

}  // namespace
}  // namespace vsurg::sim
