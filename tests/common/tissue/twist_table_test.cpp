// The nonlinear twist table (common/tissue/twist_table.h) and the reduced twist model reading it
// (reduced.h): at its levels the model is the hyperelastic FEM's state, between them it is close
// to a solve of its own, the torque curve stiffens with the exponential law, the linear field as
// a table is the linear model, and half a turn on the coarsest mesh is bounded.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry/tet_embedding.h"
#include "common/geometry/tet_generators.h"
#include "common/tissue/twist_table.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

// A bar of radius 10 mm and length 60 mm (`rings` across), its base fixed, its end grasped.
TwistTableInputs BarInputs(int rings, double stiffening, double max_twist, int levels) {
  const geometry::TetCylinder c =
      geometry::MakeTetCylinder(geometry::TorsionCylinder(0.06, 0.01, 0.01, rings)).value();
  TwistTableInputs in;
  in.mesh = c.mesh;
  in.material = {30e3, 0.45, stiffening, false};
  in.fixed = c.base;
  in.face = c.tip;
  in.display = c.mesh.positions;  // the FEM's own vertices: the fields are its state exactly
  in.max_twist = max_twist;
  in.levels = levels;
  return in;
}

double MaxGap(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

TEST(TwistTableTest, AtItsLevelsTheModelIsTheFemsStateAndBetweenThemClose) {
  const TwistTableInputs in = BarInputs(2, 0, std::numbers::pi / 2, 3);
  TwistTableReport report;
  auto table = PrecomputeTwistTable(in, &report);
  ASSERT_TRUE(table.ok()) << table.error().message;
  ASSERT_EQ(table->Levels(), 7);
  EXPECT_LT(report.worst_residual, 1e-9);
  auto model = ReducedTwistModel::Create(*table, in.display, std::numbers::pi);
  ASSERT_TRUE(model.ok()) << model.error().message;
  // Level by level the model rebuilds the FEM's positions (float fields: well under a micron).
  for (int k = 0; k < table->Levels(); ++k) {
    auto state = SolveTwisted(in, table->twist[k], nullptr, 1 + 2 * std::abs(k - 3));
    ASSERT_TRUE(state.ok()) << state.error().message;
    EXPECT_NEAR(state->torque, table->torque[k], 1e-6 * std::abs(table->torque.back()));
    model->Update(table->torque[k]);
    EXPECT_LT(MaxGap(model->positions(), state->positions), 1e-6) << "level " << k;
  }
  // Half-way between levels, against a solve of its own at the model's twist for that torque:
  // the interpolation error, a small part of the motion.
  for (const double twist : {0.25, 0.8, -1.3}) {
    auto state = SolveTwisted(in, twist, nullptr, 4);
    ASSERT_TRUE(state.ok());
    const ReducedTwistModel::Answer a = model->TorqueAt(twist);
    EXPECT_NEAR(a.torque, state->torque, 0.01 * std::abs(state->torque)) << twist;
    model->Update(a.torque);
    EXPECT_LT(MaxGap(model->positions(), state->positions),
              0.02 * MaxGap(state->positions, in.mesh.positions))
        << twist;
    EXPECT_NEAR(model->grasp_twist(a.torque), twist, 1e-9);
  }
}

TEST(TwistTableTest, TheExponentialLawStiffensWhereNeoHookesTorqueStaysNearlyLinear) {
  // Rivlin: a neo-Hookean cylinder's torque is linear in the twist; the exponential law's
  // rises faster (its shear stiffness grows with I1 − 3 = (ψr)²).
  auto curve = [](double b) {
    auto t = PrecomputeTwistTable(BarInputs(2, b, std::numbers::pi / 2, 2));
    EXPECT_TRUE(t.ok());
    return t.ok() ? t->torque : std::vector<double>(5, 0.0);
  };
  const std::vector<double> neo = curve(0), expo = curve(4);
  // Levels −π/2, −π/4, 0, π/4, π/2: the secant at π/2 against the one at π/4.
  const double neo_ratio = neo[4] / (2 * neo[3]), expo_ratio = expo[4] / (2 * expo[3]);
  EXPECT_NEAR(neo_ratio, 1.0, 0.05);
  EXPECT_GT(expo_ratio, neo_ratio + 0.05);
  // The mesh's tetrahedra have a handedness: the two directions differ by a few %.
  EXPECT_NEAR(neo[3], -neo[1], 0.05 * neo[3]);
  EXPECT_NEAR(expo[0], -expo[4], 0.05 * expo[4]);
  EXPECT_NEAR(expo[3] / neo[3], 1.0, 0.12);  // the same small-strain stiffness
}

TEST(TwistTableTest, TheLinearFieldAsATableIsTheLinearModel) {
  TwistField f;
  const std::vector<Vec3> rest = {{0.01, 0, 0}, {0, 0.02, 0.05}, {0, 0, 0.1}};
  f.angle = {0.1f, 0.3f, 0.0f};
  f.warp = {0.0f, 1e-4f, 2e-4f};
  f.radial = {0.0f, 0.01f, 0.0f};
  f.lateral = {Vec3::Zero(), Vec3::Zero(), Vec3(1e-4, 0, 0)};
  f.grasp_compliance = 0.3;
  auto model = ReducedTwistModel::Create(f, rest, 1.0);
  ASSERT_TRUE(model.ok());
  EXPECT_EQ(model->Levels(), 3);
  EXPECT_NEAR(model->torque_capacity(), 1.0 / 0.3, 1e-6);  // the field in float
  EXPECT_NEAR(model->grasp_stiffness(), 1 / 0.3, 1e-12);
  for (const double t : {-2.0, -0.5, 0.7, 3.0}) {
    model->Update(t);
    const Vec3& x = model->positions()[1];
    const double angle = std::atan2(-x.x(), x.y());
    EXPECT_NEAR(angle, 0.3 * t, 1e-5) << t;
    EXPECT_NEAR(std::hypot(x.x(), x.y()), 0.02 * (1 + 0.01 * t), 1e-7) << t;
    EXPECT_NEAR(x.z(), 0.05 + 1e-4 * t, 1e-9) << t;
    EXPECT_NEAR(model->positions()[2].x(), 1e-4 * t, 1e-9) << t;
    const ReducedTwistModel::Answer a = model->TorqueAt(0.3 * t);
    EXPECT_NEAR(a.torque, t, 1e-12);
    EXPECT_FALSE(a.overload);
  }
  const ReducedTwistModel::Answer past = model->TorqueAt(-2.0);
  EXPECT_TRUE(past.overload);
  EXPECT_NEAR(past.torque, -1.0 / 0.3, 1e-6);
  EXPECT_EQ(past.stiffness, 0);
}

TEST(TwistTableTest, HalfATurnOnTheCoarsestMeshIsBoundedAndABadTableRefused) {
  const TwistTableInputs in = BarInputs(1, 2, std::numbers::pi, 2);
  auto table = PrecomputeTwistTable(in);
  ASSERT_TRUE(table.ok()) << table.error().message;
  auto model = ReducedTwistModel::Create(*table, in.display, std::numbers::pi);
  ASSERT_TRUE(model.ok());
  for (double t = -1.2 * model->torque_capacity(); t <= 1.2 * model->torque_capacity();
       t += 0.05 * model->torque_capacity()) {
    const ReducedStats s = model->Update(t);
    EXPECT_TRUE(s.ok);
    for (const Vec3& x : model->positions()) ASSERT_TRUE(x.allFinite());
  }
  EXPECT_FALSE(model->Update(std::numeric_limits<double>::quiet_NaN()).ok);
  // The grasp's face turns by the level's angle: at the last level, half a turn.
  model->Update(table->torque.back());
  int rim = in.face[0];
  for (int v : in.face)
    if (in.display[v].head<2>().norm() > in.display[rim].head<2>().norm()) rim = v;
  const Vec3& far = model->positions()[rim];
  const Vec3& far0 = in.display[rim];
  EXPECT_NEAR(std::abs(std::atan2(far0.x() * far.y() - far0.y() * far.x(),
                                  far0.x() * far.x() + far0.y() * far.y())),
              std::numbers::pi, 1e-4);
  // Between the last two levels (a quarter and half a turn) the rim turns on through 3π/4.
  const int n = table->Levels();
  model->Update(0.5 * (table->torque[n - 2] + table->torque[n - 1]));
  EXPECT_NEAR(
      std::atan2(far0.x() * far.y() - far0.y() * far.x(), far0.x() * far.x() + far0.y() * far.y()),
      0.75 * std::numbers::pi, 0.1);
  // A level whose atan2 read a turn past π as its negative is made continuous with the level
  // inside it, on both sides of rest.
  TwistTable wrapped = *table;
  const size_t nv = in.display.size();
  wrapped.angle[(n - 1) * nv + rim] = static_cast<float>(-std::numbers::pi + 0.04);
  wrapped.angle[rim] = static_cast<float>(std::numbers::pi - 0.04);
  ContinuousAngles(wrapped);
  EXPECT_NEAR(wrapped.angle[(n - 1) * nv + rim], std::numbers::pi + 0.04, 1e-5);
  EXPECT_NEAR(wrapped.angle[rim], -std::numbers::pi - 0.04, 1e-5);
  EXPECT_EQ(wrapped.angle[(n - 2) * nv + rim], table->angle[(n - 2) * nv + rim]);
  // Refused: levels that do not rise, a table without rest, a NaN field, bad inputs.
  TwistTable bad = *table;
  std::swap(bad.torque[0], bad.torque[1]);
  EXPECT_FALSE(ReducedTwistModel::Create(bad, in.display, 1.0).ok());
  bad = *table;
  bad.twist[2] = 0.01;
  EXPECT_FALSE(ValidateTwistTable(bad, in.display.size()).ok());
  bad = *table;
  bad.angle[7] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(ValidateTwistTable(bad, in.display.size()).ok());
  TwistTableInputs wrong = in;
  wrong.max_twist = 4;
  EXPECT_FALSE(PrecomputeTwistTable(wrong).ok());
  wrong = in;
  wrong.face = {-1};
  EXPECT_FALSE(PrecomputeTwistTable(wrong).ok());
}

// The relaxation carried to the torque against the FEM's own, per element: the bar turned to
// 60° in 0.1 s and held for 1.5 s (two Prony terms, 0.2 and 1 s), the reduced model's elastic
// torque from its table convolved by TorqueRelaxation; and the closed form of a step held, the
// standard linear solid's T(t) = T_e·G(t).
TEST(TwistTableTest, TheTorqueRelaxesAsTheFemsStressDoes) {
  const std::vector<PronyTerm> terms = {{0.3, 0.2}, {0.2, 1.0}};
  const TwistTableInputs in = BarInputs(1, 2, std::numbers::pi / 3, 4);
  auto table = PrecomputeTwistTable(in);
  ASSERT_TRUE(table.ok()) << table.error().message;
  auto model = ReducedTwistModel::Create(*table, in.display, std::numbers::pi);
  ASSERT_TRUE(model.ok());
  auto relax = TorqueRelaxation::Create(terms);
  ASSERT_TRUE(relax.ok());
  EXPECT_NEAR(relax->relaxed_share(), 0.5, 1e-15);
  auto fem = HyperelasticFem::Create(in.mesh, in.material);
  ASSERT_TRUE(fem.ok());
  ASSERT_TRUE(fem->SetRelaxation(terms).ok());
  for (int v : in.fixed)
    for (int a = 0; a < 3; ++a) fem->Hold(v, a, in.mesh.positions[v][a]);
  const Vec3 axis = Vec3::UnitZ();
  double sum2 = 0, norm2 = 0, peak = 0, last_fem = 0, last_reduced = 0;
  for (double t = 0; t < 1.6 - 1e-9;) {
    const double dt = t < 0.1 - 1e-9 ? 0.01 : 0.05;
    t += dt;
    const double twist = std::numbers::pi / 3 * std::min(t / 0.1, 1.0);
    for (int v : in.face) {
      const Vec3 p = Eigen::AngleAxisd(twist, axis) * in.mesh.positions[v];
      for (int a = 0; a < 3; ++a) fem->Hold(v, a, p[a]);
    }
    ASSERT_TRUE(fem->Step(dt, 1e-9).converged) << t;
    const Eigen::VectorXd f = fem->InternalForces();
    double torque = 0;
    for (int v : in.face) torque += fem->positions()[v].cross(Vec3(-f.segment<3>(3 * v))).dot(axis);
    const double elastic = model->TorqueAt(twist).torque;
    const double reduced = relax->Torque(elastic, dt);
    relax->Commit(elastic, dt);
    sum2 += (reduced - torque) * (reduced - torque), norm2 += torque * torque;
    peak = std::max(peak, torque), last_fem = torque, last_reduced = reduced;
  }
  EXPECT_LT(std::sqrt(sum2 / norm2), 0.01) << "RMS over the ramp and hold";  // 0.07% here
  EXPECT_LT(last_fem, 0.75 * peak);                                          // it relaxed
  EXPECT_NEAR(last_reduced, last_fem, 0.02 * last_fem);
  // A step of the elastic torque held: T(t) = T_e·G(t) at any step size.
  for (const double h : {1e-3, 0.05}) {
    relax->Reset();
    relax->Commit(1.0, 1e-9);
    double t = 0;
    for (int k = 0; k < 40; ++k) t += h, relax->Commit(1.0, h);
    const double g = 0.5 + 0.3 * std::exp(-t / 0.2) + 0.2 * std::exp(-t / 1.0);
    EXPECT_NEAR(relax->Torque(1.0, 0.0), g, 1e-9) << h;
  }
  EXPECT_FALSE(TorqueRelaxation::Create({{0.6, 1.0}, {0.5, 1.0}}).ok());
  EXPECT_FALSE(TorqueRelaxation::Create({{0.2, 0.0}}).ok());
  EXPECT_FALSE(TorqueRelaxation::Create({{-0.1, 1.0}}).ok());
  EXPECT_FALSE(TorqueRelaxation::Create({{0.2, std::numeric_limits<double>::infinity()}}).ok());
}

}  // namespace
}  // namespace vsurg::tissue
