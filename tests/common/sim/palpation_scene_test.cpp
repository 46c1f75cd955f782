// A palpation's scene: the block mesh, the palpate task, the cases it draws, and bad input named
// by its field (common/sim/scene.h, common/sim/palpation_case.h).
#include <gtest/gtest.h>

#include "common/sim/palpation_case.h"
#include "common/sim/scene.h"

namespace vsurg::sim {
namespace {

std::string Pad(const std::string& task, const std::string& mesh = "") {
  return R"({"name": "pad", "mesh": )" +
         (mesh.empty() ? R"({"type": "block", "size": [0.1, 0.1, 0.03], "cells": [10, 10, 3]})"
                       : mesh) +
         R"(, "regions": [{"name": "r", "model": {"type": "reduced", "mode": "contact"}}],
         "task": )" +
         task + R"(, "error_budget": {"rms": 0.2}})";
}

std::string Refused(const std::string& text) {
  auto s = ParseScene(text, "x.json");
  EXPECT_FALSE(s.ok()) << text;
  return s.ok() ? "" : s.error().message;
}

TEST(PalpationSceneTest, TheLumpSearchSceneDrawsItsCasesOnAPad) {
  auto scene = LoadSceneByName("lump-search");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->mesh.kind, MeshKind::kBlock);
  EXPECT_EQ(scene->task.kind, scoring::TaskKind::kPalpate);
  ASSERT_TRUE(scene->cases.has_value());
  EXPECT_EQ(scene->cases->min_count, 0);
  EXPECT_EQ(scene->cases->max_count, 2);
  EXPECT_DOUBLE_EQ(scene->cases->min_diameter, 0.008);
  EXPECT_DOUBLE_EQ(scene->case_margin, 0.025);
  EXPECT_TRUE(scene->inclusions.empty());
  // The pad's surface is its FEM grid's boundary: every grid node on a face, nothing inside.
  auto mesh = BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok());
  EXPECT_EQ(mesh->surface.VertexCount(), 21 * 21 * 9 - 19 * 19 * 7);
  EXPECT_NEAR(geometry::SignedVolume(mesh->surface), 0.12 * 0.12 * 0.04, 1e-9);
}

TEST(PalpationSceneTest, APalpationNeedsAContactModelAndNoTarget) {
  auto ok = ParseScene(Pad(R"({"type": "palpate", "time_limit_s": 200})"), "x.json");
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(ok->task.hold_s, 0);
  EXPECT_FALSE(ok->cases.has_value());
  // A course cannot give a palpation a target: it has none.
  scoring::TaskSettings target;
  target.target = 0.005;
  EXPECT_FALSE(scoring::ApplyTaskSettings(ok->task, target).ok());
  scoring::TaskSettings limit;
  limit.time_limit = 100;
  EXPECT_TRUE(scoring::ApplyTaskSettings(ok->task, limit).ok());
  std::string twist = Pad(R"({"type": "palpate"})");
  twist.replace(twist.find(R"("mode": "contact")"), 17, R"("mode": "surface-twist")");
  EXPECT_NE(Refused(twist).find("task.type"), std::string::npos);
}

TEST(PalpationSceneTest, BadCasesAndBlocksNameTheirField) {
  const auto cases = [](const std::string& body) {
    return Pad(R"({"type": "palpate", "cases": )" + body + "}");
  };
  const std::pair<std::string, const char*> bad[] = {
      {cases(R"({"count": [2, 1]})"), "task.cases"},
      {cases(R"({"count": [0, 40]})"), "task.cases.count"},
      {cases(R"({"count": [0.5, 1]})"), "task.cases.count"},
      {cases(R"({"diameter_mm": [0, 10]})"), "task.cases"},
      {cases(R"({"depth_mm": [10, 5]})"), "task.cases"},
      {cases(R"({"contrast": [0, 5]})"), "task.cases"},
      {cases(R"({"contrast": [3, "x"]})"), "task.cases.contrast"},
      {cases(R"({"gap_mm": -1})"), "task.cases.gap_mm"},
      {cases(R"({"margin_mm": "wide"})"), "task.cases.margin_mm"},
      {Pad(R"({"type": "press", "target_depth_m": 0.005, "tolerance_m": 0.001, "cases": {}})"),
       "task.cases: only a palpation"},
      {Pad(R"({"type": "palpate"})", R"({"type": "block", "size": [0.1, 0, 0.03],
           "cells": [10, 10, 3]})"),
       "mesh.size"},
      {Pad(R"({"type": "palpate"})", R"({"type": "block", "size": [0.1, 0.1, 0.03],
           "cells": [10, 10, 2.5]})"),
       "mesh.cells"},
      {Pad(R"({"type": "palpate"})", R"({"type": "block", "size": [0.1, 0.1, 0.03]})"),
       "mesh.cells"},
  };
  for (const auto& [text, field] : bad)
    EXPECT_NE(Refused(text).find(field), std::string::npos) << text << ": " << Refused(text);
}

// A margin the pad cannot keep is refused when a case is drawn, naming it.
TEST(PalpationSceneTest, AMarginWiderThanThePadIsRefusedWhenACaseIsDrawn) {
  auto scene = ParseScene(Pad(R"({"type": "palpate", "cases": {"margin_mm": 60}})"), "x.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  auto drawn = DrawCase(*scene, 1);
  ASSERT_FALSE(drawn.ok());
  EXPECT_EQ(drawn.error().field, "task.cases.margin_mm");
  auto plain = ParseScene(Pad(R"({"type": "palpate"})"), "x.json");
  ASSERT_TRUE(plain.ok());
  auto same = DrawCase(*plain, 1);  // no cases: the scene as it is
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(same->name, "pad");
}

}  // namespace
}  // namespace vsurg::sim
