// Four-handed training's shared tool (common/sim/guidance.h): the modes' forces, the ramps, the
// hand-back when the instructor goes silent, the passivity of the shared part without delay, and
// a simulation answering both hands.
#include "common/sim/guidance.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/sim/simulation.h"

namespace vsurg::sim {
namespace {

using haptics::StylusSample;
using haptics::Vec3;

StylusSample At(const Vec3& x) {
  StylusSample s;
  s.position = x;
  return s;
}

// Ramps a guidance to its request with an instructor at x_i (trainee clock from t).
double Settle(Guidance& g, const Vec3& x_i, double t = 0) {
  for (int k = 0; k < 2000; ++k, t += 1e-3) {
    g.SetInstructor(At(x_i), t);
    g.Advance(t);
  }
  return t;
}

TEST(GuidanceTest, ARequestIsCheckedAndTheModesHaveTheirNames) {
  EXPECT_TRUE(CheckGuideRequest({GuideMode::kGuide, 0.5}).ok());
  EXPECT_TRUE(CheckGuideRequest({GuideMode::kObserve, 0}).ok());
  EXPECT_FALSE(CheckGuideRequest({GuideMode::kGuide, 1.5}).ok());
  EXPECT_FALSE(CheckGuideRequest({GuideMode::kGuide, -0.1}).ok());
  EXPECT_FALSE(CheckGuideRequest({GuideMode::kGuide, std::nan("")}).ok());
  EXPECT_FALSE(CheckGuideRequest({GuideMode::kObserve, 0.5}).ok());  // α is the guide mode's
  EXPECT_FALSE(CheckGuideRequest({static_cast<GuideMode>(7), 0}).ok());
  EXPECT_EQ(*ParseGuideMode("observe"), GuideMode::kObserve);
  EXPECT_FALSE(ParseGuideMode("drive").ok());
}

TEST(GuidanceTest, ObserveLeavesTheTraineeAloneAndLeadsTheInstructor) {
  Guidance g;
  g.Request({GuideMode::kObserve, 0});
  const Vec3 x_t(0, 0, 0), x_i(0.01, 0, 0), tissue(0, 0, 1.0);
  Settle(g, x_i);
  EXPECT_DOUBLE_EQ(g.alpha(), 0);
  EXPECT_DOUBLE_EQ(g.follow(), 1);
  EXPECT_EQ(g.Tool(At(x_t)).position, x_t);
  EXPECT_TRUE((g.TraineeForce(tissue, x_t) - tissue).norm() < 1e-12);
  // The instructor feels the tissue and is pulled to the trainee's tool.
  const Vec3 f_i = g.InstructorForce(tissue, x_t, x_i);
  EXPECT_NEAR(f_i.z(), 1.0, 1e-12);
  EXPECT_NEAR(f_i.x(), -Guidance::kCouplingStiffness * 0.01, 1e-12);
}

TEST(GuidanceTest, GuideSharesTheToolAndTheForcesSumToTheTissuesOnIt) {
  Guidance g;
  g.Request({GuideMode::kGuide, 0.25});
  const Vec3 x_t(0, 0, 0), x_i(0.02, 0, -0.01), tissue(0.2, 0, 1.0);
  Settle(g, x_i);
  ASSERT_NEAR(g.alpha(), 0.25, 1e-9);
  EXPECT_TRUE((g.Tool(At(x_t)).position - 0.25 * x_i).norm() < 1e-12);
  // The coupling is one spring between the hands: equal and opposite; the rest is the tissue's.
  const Vec3 sum = g.TraineeForce(tissue, x_t) + g.InstructorForce(tissue, x_t, x_i);
  EXPECT_TRUE((sum - tissue).norm() < 1e-12);
  // The tissue's share of the slope: (1 − α)²·J for the trainee; the coupling is the stations'.
  const Eigen::Matrix3d j = -300 * Eigen::Matrix3d::Identity();
  EXPECT_NEAR(g.TraineeSlope(j)(0, 0), 0.75 * 0.75 * -300, 1e-9);
}

// A station's model of its answer (the force at its sample, the tissue's slope, the coupling it
// evaluates itself) is each hand's force wherever the hand has moved since, below the coupling's
// cap and past it. A slope k_c·I through the cap instead gave a hand a round trip behind k_c
// times its lag on top of a pull the server held at 1.5 N.
TEST(GuidanceTest, TheStationsModelsAreTheHandsForcesOnBothSidesOfTheCap) {
  for (const GuideRequest r : {GuideRequest{GuideMode::kObserve, 0}, {GuideMode::kGuide, 0.4}})
    for (const double gap : {0.004, 0.03}) {
      Guidance g;
      g.Request(r);
      const Vec3 x_t(0.001, -0.002, 0.0), x_i = x_t + Vec3(gap, 0.3 * gap, -0.5 * gap);
      Settle(g, x_i);
      const Vec3 tissue(0.1, 0.2, 0.9);  // J = 0: a constant tissue force, the coupling alone
      haptics::LocalModel mi;
      mi.force0 = g.InstructorForce(tissue, x_t, x_i);
      mi.position0 = x_i;
      mi.jacobian = g.InstructorSlope(Eigen::Matrix3d::Zero());
      mi.pull_target = x_t;
      mi.pull_gain = g.InstructorGain();
      haptics::LocalModel mt;
      mt.force0 = g.TraineeForce(tissue, x_t);
      mt.position0 = x_t;
      mt.pull_target = x_i;
      mt.pull_gain = g.alpha();
      // The instructor catching up (the lag gone, the gap's half, past the trainee) and the
      // trainee moving away from the instructor.
      for (const double s : {1.0, 0.5, -0.3}) {
        const Vec3 xi = x_t + s * (x_i - x_t);
        EXPECT_LT((mi.ForceAt(xi) - g.InstructorForce(tissue, x_t, xi)).norm(), 1e-12)
            << "gap " << gap << ", at " << s;
        const Vec3 xt = x_t - (1 - s) * (x_i - x_t);
        EXPECT_LT((mt.ForceAt(xt) - g.TraineeForce(tissue, xt)).norm(), 1e-12) << "gap " << gap;
      }
    }
}

// Without delay the shared tool is as passive as the tissue: two hands moving round closed loops
// at constant α against a linear spring tissue (conservative) get back no net energy, and against
// a spring-damper (dissipative) they lose it.
TEST(GuidanceTest, TheSharedToolIsPassiveWithoutDelay) {
  for (const double damping : {0.0, 2.0}) {
    Guidance g;
    g.Request({GuideMode::kGuide, 0.6});
    double t = Settle(g, Vec3::Zero());
    const double k_tissue = 300, dt = 1e-4;
    double energy = 0;  // Σ F·dx over both hands, by the trapezoid (exact for a spring's)
    Vec3 xt_prev(0, 0, 0), xi_prev(0, 0, 0), xv_prev = Vec3::Zero();
    Vec3 ft_prev = Vec3::Zero(), fi_prev = Vec3::Zero();
    for (int k = 1; k <= 20000; ++k) {
      const double ph = 2 * M_PI * k * dt;  // two seconds: two loops
      const Vec3 x_t(0.01 * std::sin(ph), 0.004 * (1 - std::cos(ph)), 0);
      const Vec3 x_i(0.006 * (1 - std::cos(ph)), 0, 0.01 * std::sin(2 * ph));
      g.SetInstructor(At(x_i), t);
      g.Advance(t);
      t += dt;
      const Vec3 x_v = g.Tool(At(x_t)).position;
      const Vec3 tissue = -k_tissue * x_v - damping * (x_v - xv_prev) / dt;
      const Vec3 f_t = g.TraineeForce(tissue, x_t), f_i = g.InstructorForce(tissue, x_t, x_i);
      energy += 0.5 * ((f_t + ft_prev).dot(x_t - xt_prev) + (f_i + fi_prev).dot(x_i - xi_prev));
      xt_prev = x_t, xi_prev = x_i, xv_prev = x_v, ft_prev = f_t, fi_prev = f_i;
    }
    if (damping == 0) {
      EXPECT_NEAR(energy, 0, 2e-6);
    } else {
      EXPECT_LT(energy, -1e-4);
    }
  }
}

TEST(GuidanceTest, ModesRampAndASilentInstructorHandsTheToolBack) {
  Guidance g;
  g.Request({GuideMode::kGuide, 1.0});
  double t = 1e-3;  // the trial clock's first advance from 0
  double before = 0;
  for (int k = 0; k < 300; ++k, t += 1e-3) {  // 0.3 s: a take-over takes 0.5
    g.SetInstructor(At(Vec3::Zero()), t);
    g.Advance(t);
    EXPECT_LE(g.alpha() - before, Guidance::kRampPerS * 1e-3 + 1e-12);
    before = g.alpha();
  }
  EXPECT_NEAR(g.alpha(), 0.6, 1e-9);
  // The instructor's samples stop: after kStaleS the tool ramps back to the trainee.
  for (int k = 0; k < 1000; ++k, t += 1e-3) g.Advance(t);
  EXPECT_DOUBLE_EQ(g.alpha(), 0);
  EXPECT_FALSE(g.shared());
}

// A simulation answers both hands: guided at α = 1 the tissue meets the instructor's tool (pressed
// into the sphere) while the trainee's hovers above; the trainee is pulled towards it, and the
// trial records the guided share.
TEST(GuidanceTest, ASimulationPutsTheDominantHandsToolOnTheTissue) {
  auto scene = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(scene.ok());
  SimulationOptions so;
  so.threaded = false;
  auto sim = Simulation::Create(*scene, so);
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  const geometry::TriMesh& rest = (*sim)->rest_mesh();
  Vec3 top = rest.positions[0];
  for (const Vec3& p : rest.positions)
    if (p.z() > top.z()) top = p;
  const Vec3 above = top + Vec3(0, 0, 0.02), inside = top - Vec3(0, 0, 0.004);
  haptics::ForceCommand trainee, instructor;
  for (int k = 0; k < 3000; ++k) {
    // The trainee alone for a second (the start-up gate opens), then the take-over.
    if (k == 1000) (*sim)->RequestGuidance({GuideMode::kGuide, 1.0});
    StylusSample i = At(k < 1000 ? above : inside), t = At(above);
    i.time = t.time = k * 1e-3;
    instructor = (*sim)->OnInstructorStylus(i);
    trainee = (*sim)->OnStylus(t);
    (*sim)->StepDeformation();
  }
  EXPECT_TRUE(trainee.shared);
  EXPECT_NEAR(trainee.guide_alpha, 1.0, 1e-9);
  EXPECT_TRUE(trainee.contact);          // the tool, not the trainee's hovering tip
  EXPECT_LT(trainee.force.z(), -1.0);    // the trainee led down towards the instructor's tool
  EXPECT_GT(instructor.force.z(), 0.3);  // the instructor feels the tissue push back
  EXPECT_EQ(trainee.local.kind, haptics::LocalModel::Kind::kLinear);
  const scoring::TrialMetrics m = (*sim)->Metrics();
  EXPECT_NEAR(m.guided_share, 2.0 / 3, 0.02);
  EXPECT_GT(m.guided_alpha, 0.8);  // its ramp included
}

}  // namespace
}  // namespace vsurg::sim
