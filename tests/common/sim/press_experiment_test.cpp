// The press experiment (the mass-spring paper) in-process: the tool's push is felt as a restoring
// force that grows with depth, a hard-but-stable case stays finite, and bad specs name their field.
#include "common/sim/press_experiment.h"

#include <gtest/gtest.h>

#include <cmath>

namespace vsurg::sim {
namespace {

PressExperimentSpec Small(double press) {
  PressExperimentSpec s;
  s.particles = 256;
  s.steps = 3000;   // 3 s: settled (kinetic energy ~1e-13 J)
  s.damping = 0.2;  // N·s/m
  s.press = press;
  return s;
}

TEST(PressExperimentTest, TheTissuePushesBackHarderTheDeeperItIsPressed) {
  auto shallow = RunPressExperiment(Small(0.002));
  auto deep = RunPressExperiment(Small(0.004));
  ASSERT_TRUE(shallow.ok() && deep.ok());
  EXPECT_EQ(shallow->steps, 3000);
  EXPECT_FALSE(deep->diverged);
  EXPECT_GT(shallow->contact_force, 0) << "the tissue resists the press";
  EXPECT_GT(deep->contact_force, shallow->contact_force);
  EXPECT_GT(deep->potential_energy, shallow->potential_energy);
  EXPECT_NEAR(deep->max_displacement, 0.004, 1e-9) << "the pressed vertex moved the most";
  EXPECT_LT(deep->kinetic_energy, 1e-3 * deep->potential_energy) << "at rest when measured";
  EXPECT_GT(deep->particles, 200);
}

TEST(PressExperimentTest, AStiffImplicitRunStaysFinite) {
  PressExperimentSpec s = Small(0.004);
  s.stiffness = 5000;  // explicit midpoint at dt = 1 ms would not survive this
  s.integrator = tissue::Integrator::kImplicitEuler;
  auto r = RunPressExperiment(s);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->diverged);
  EXPECT_TRUE(std::isfinite(r->contact_force));
  EXPECT_GT(r->cg_iterations_last, 0);
}

TEST(PressExperimentTest, BadSpecsNameTheirField) {
  PressExperimentSpec s = Small(0.002);
  s.dt = 0;
  EXPECT_EQ(RunPressExperiment(s).error().field, "dt");
  s = Small(0.5);
  EXPECT_EQ(RunPressExperiment(s).error().field, "press");
  s = Small(0.002);
  s.mesh = "/no/such/file.obj";
  EXPECT_EQ(RunPressExperiment(s).error().field, "mesh");
  s = Small(0.002);
  s.stiffness = -1;
  EXPECT_EQ(RunPressExperiment(s).error().field, "structural_stiffness");
}

}  // namespace
}  // namespace vsurg::sim
