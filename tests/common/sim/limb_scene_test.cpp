#include "common/sim/limb_scene.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace vsurg::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

TEST(LimbSceneTest, ArmTwistsSixtyDegreesAtPaperTorque) {
  auto scene = BuiltinLimbScene("arm");
  ASSERT_TRUE(scene.ok());
  auto inst = Instantiate(*scene);
  ASSERT_TRUE(inst.ok()) << inst.error().message;
  EXPECT_NEAR(inst->model.Capacity(), 3.30, 1e-9);  // largest forearm rotation torque
  // The coils tile the forearm from the wrist to the elbow.
  EXPECT_NEAR(inst->model.RingRadius(inst->model.coils()), scene->limb.length, 1e-12);
  const tissue::DeformStats st = inst->deformer.Update(2.07);
  EXPECT_NEAR(st.total_twist, 60 * kDeg, 0.5 * kDeg);
  EXPECT_FALSE(st.overload);
  EXPECT_GT(st.cutoff, 1);
  EXPECT_LT(st.cutoff, inst->model.coils());
}

TEST(LimbSceneTest, CalfTwistsThirtyDegreesAtPaperTorque) {
  auto scene = BuiltinLimbScene("calf");
  ASSERT_TRUE(scene.ok());
  auto inst = Instantiate(*scene);
  ASSERT_TRUE(inst.ok());
  EXPECT_NEAR(inst->model.Capacity(), 6.0, 1e-9);
  EXPECT_NEAR(inst->model.RingRadius(inst->model.coils()), scene->limb.length, 1e-12);
  EXPECT_NEAR(inst->deformer.Update(2.07).total_twist, 30 * kDeg, 0.5 * kDeg);
}

TEST(LimbSceneTest, ElbowStaysFixedEvenWhenOverloaded) {
  auto inst = Instantiate(*BuiltinLimbScene("arm"));
  ASSERT_TRUE(inst.ok());
  const tissue::DeformStats st = inst->deformer.Update(10.0);
  EXPECT_TRUE(st.overload);
  for (int v = 0; v < inst->limb.surface.VertexCount(); ++v) {
    if (inst->limb.surface.positions[v].z() == 0.0) {
      EXPECT_EQ(inst->deformer.positions()[v], inst->limb.surface.positions[v]);
    }
  }
}

TEST(LimbSceneTest, UnknownSceneIsNotFound) {
  auto scene = BuiltinLimbScene("spleen");
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.error().code, ErrorCode::kNotFound);
  EXPECT_EQ(scene.error().field, "scene");
}

}  // namespace
}  // namespace vsurg::sim
