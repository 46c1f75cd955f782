// A node's default capacity from its scenes' measured cost per station: the arithmetic, the
// dearest scene of a folder, the shipped scenes all stating theirs, and a bad cost refused by name.
#include "server/cluster/node_cost.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/sim/scene.h"

namespace vsurg::server {
namespace {

namespace fs = std::filesystem;

TEST(NodeCostTest, SeventyPercentOfTheCoresAtTheCostIsTheCapacity) {
  EXPECT_EQ(CapacityAtCost(2, 0.28), 5);      // 1.4 / 0.28
  EXPECT_EQ(CapacityAtCost(2, 0.0093), 150);  // a pressing station's
  EXPECT_EQ(CapacityAtCost(8, 0.28), 20);
  EXPECT_EQ(CapacityAtCost(2, 0.28, 1.0), 7);
  EXPECT_EQ(CapacityAtCost(2, 5.0), 1) << "a node takes at least one session";
  EXPECT_EQ(CapacityAtCost(64, 1e-4), 4096) << "within --capacity's range";
  EXPECT_EQ(CapacityAtCost(2, 0), 0) << "no cost, no derived capacity";
  EXPECT_EQ(CapacityAtCost(2, std::nan("")), 0);
}

TEST(NodeCostTest, TheNodesCoresAreItsAffinityAtMost) {
  const double cores = NodeCores();
  EXPECT_GE(cores, 1);
  EXPECT_LE(cores, std::max(1u, std::thread::hardware_concurrency()));
}

// The shipped sphere's scene under another name, with `cost` (JSON text) as its cost, or none.
std::string SceneWithCost(const std::string& name, const std::string& cost) {
  std::ifstream in(std::string(VSURG_SOURCE_DIR) + "/scenes/sphere-palpation-256.json");
  nlohmann::json scene = nlohmann::json::parse(in);
  scene["name"] = name;
  scene.erase("cost");
  if (!cost.empty()) scene["cost"] = nlohmann::json::parse(cost);
  return scene.dump();
}

TEST(NodeCostTest, TheDearestSceneThatStatesItsCostIsFound) {
  const fs::path dir = fs::temp_directory_path() / ("vsurg-node-cost-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / (name + ".json")) << text;
  };
  write("cheap", SceneWithCost("cheap", R"({"core_per_station": 0.02})"));
  write("dear", SceneWithCost("dear", R"({"core_per_station": 0.3})"));
  write("unstated", SceneWithCost("unstated", ""));
  write("broken", "{ not json");
  const DearestScene d = FindDearestScene(dir.string());
  fs::remove_all(dir);
  EXPECT_EQ(d.name, "dear");
  EXPECT_DOUBLE_EQ(d.core_per_station, 0.3);
  EXPECT_EQ(d.scenes, 3) << "the broken file is not a scene";
  EXPECT_EQ(d.stated, 2);
}

TEST(NodeCostTest, EveryShippedSceneStatesItsCost) {
  const DearestScene d = FindDearestScene(std::string(VSURG_SOURCE_DIR) + "/scenes");
  EXPECT_GT(d.scenes, 10);
  EXPECT_EQ(d.stated, d.scenes) << "a scene without its cost leaves the default at 24";
  EXPECT_GT(d.core_per_station, 0);
}

TEST(NodeCostTest, ABadCostIsRefusedByName) {
  for (const char* cost :
       {R"({"core_per_station": 0})", R"({"core_per_station": -1})",
        R"({"core_per_station": "cheap"})", R"({"core_per_station": 65})", R"("cheap")", "{}"}) {
    auto scene = sim::ParseScene(SceneWithCost("bad", cost), "bad.json");
    ASSERT_FALSE(scene.ok()) << cost;
    EXPECT_NE(scene.error().field.find("cost"), std::string::npos)
        << cost << ": " << scene.error().field;
  }
  auto good = sim::ParseScene(SceneWithCost("good", R"({"core_per_station": 0.25})"), "good.json");
  ASSERT_TRUE(good.ok()) << good.error().message;
  EXPECT_DOUBLE_EQ(good->core_per_station, 0.25);
}

}  // namespace
}  // namespace vsurg::server
