#include "common/tissue/mass_spring.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::tissue {
namespace {

constexpr double kRest = 0.1;  // m, rest length of the oscillator spring

// A particle on a spring to a fixed particle, moving along the spring: a 1-D damped
// oscillator m ẍ + c ẋ + k x = 0 with x the stretch.
MassSpringModel Oscillator(Integrator integrator, double k, double c, double m, double stretch) {
  MassSpringSystem s;
  s.rest_positions = {Vec3::Zero(), Vec3(kRest, 0, 0)};
  s.masses = {1.0, m};
  s.springs = {{0, 1, k, c, kRest}};
  MassSpringStepParams p;
  p.integrator = integrator;
  p.divergence_distance = 1e6;
  p.cg_energy_floor = 0;  // an integrator's own behaviour, its solve exact at any energy
  auto model = MassSpringModel::Create(s, p);
  EXPECT_TRUE(model.ok());
  model->SetFixed(0, true);
  // Start stretched, at rest: place the state by one kinematic jump.
  model->SetKinematic(1, true);
  model->SetKinematicTarget(1, Vec3(kRest + stretch, 0, 0));
  model->Step(1.0);
  model->SetKinematic(1, false);  // released with zero velocity
  return *model;
}

// Exact stretch at time t of the underdamped oscillator released from x0 at rest.
double Exact(double k, double c, double m, double x0, double t) {
  const double w0 = std::sqrt(k / m), zeta = c / (2 * std::sqrt(k * m));
  const double wd = w0 * std::sqrt(1 - zeta * zeta);
  return std::exp(-zeta * w0 * t) *
         (x0 * std::cos(wd * t) + zeta * w0 * x0 / wd * std::sin(wd * t));
}

// Largest error along the trajectory (a single end time can sit on a zero crossing of the error).
double ErrorAt(Integrator integrator, int steps) {
  const double k = 4 * std::numbers::pi * std::numbers::pi, c = 0.5, m = 1.0, x0 = 0.01,
               t_end = 1.3;
  MassSpringModel model = Oscillator(integrator, k, c, m, x0);
  const double h = t_end / steps;
  double worst = 0;
  for (int i = 1; i <= steps; ++i) {
    model.Step(h);
    worst = std::max(worst, std::abs(model.positions()[1].x() - kRest - Exact(k, c, m, x0, i * h)));
  }
  return worst;
}

TEST(MassSpringTest, IntegratorsConvergeAtTheirOrders) {
  struct Case {
    Integrator integrator;
    double order;
    int steps;
  };
  const Case cases[] = {
      {Integrator::kExplicitEuler, 1, 800}, {Integrator::kSymplecticEuler, 1, 800},
      {Integrator::kMidpoint, 2, 400},      {Integrator::kRk4, 4, 50},
      {Integrator::kVerlet, 2, 400},        {Integrator::kImplicitEuler, 1, 800}};
  for (const Case& c : cases) {
    const double e1 = ErrorAt(c.integrator, c.steps), e2 = ErrorAt(c.integrator, 2 * c.steps);
    const double slope = std::log2(e1 / e2);
    EXPECT_NEAR(slope, c.order, 0.2)
        << IntegratorName(c.integrator) << ": errors " << e1 << ", " << e2;
  }
}

struct EnergyTrace {
  double first = 0, last = 0, min = 1e300, max = 0;
};

EnergyTrace UndampedEnergy(Integrator integrator, double omega_dt, int steps) {
  MassSpringModel model = Oscillator(integrator, 1.0, 0.0, 1.0, 1e-3);  // ω = 1 rad/s
  EnergyTrace e;
  e.first = model.KineticEnergy() + model.PotentialEnergy();
  for (int i = 0; i < steps; ++i) {
    model.Step(omega_dt);
    const double now = model.KineticEnergy() + model.PotentialEnergy();
    e.min = std::min(e.min, now);
    e.max = std::max(e.max, now);
  }
  e.last = model.KineticEnergy() + model.PotentialEnergy();
  return e;
}

// DESIGN.md "Model 2": the known energy behaviour, over 10⁵ steps at ω·dt = 0.01.
TEST(MassSpringTest, EnergyOfAnUndampedSpringBehavesAsEachIntegratorPromises) {
  constexpr int kSteps = 100000;
  const EnergyTrace explicit_euler = UndampedEnergy(Integrator::kExplicitEuler, 0.01, kSteps);
  EXPECT_GT(explicit_euler.last / explicit_euler.first, 1000.0);  // (1 + (ωh)²)^n = e^10
  const EnergyTrace midpoint = UndampedEnergy(Integrator::kMidpoint, 0.01, kSteps);
  EXPECT_GT(midpoint.last / midpoint.first, 1.0 + 1e-4);  // (1 + (ωh)⁴/4)^n − 1 ≈ 2.5e-4
  EXPECT_LT(midpoint.last / midpoint.first, 1.0 + 1e-3);
  const EnergyTrace symplectic = UndampedEnergy(Integrator::kSymplecticEuler, 0.01, kSteps);
  EXPECT_LT(symplectic.max / symplectic.first, 1.01);  // oscillates by about ωh/2, no drift
  EXPECT_GT(symplectic.min / symplectic.first, 0.99);
  const EnergyTrace verlet = UndampedEnergy(Integrator::kVerlet, 0.01, kSteps);
  EXPECT_LT(verlet.max / verlet.first, 1.0 + 1e-4);
  EXPECT_GT(verlet.min / verlet.first, 1.0 - 1e-4);
  const EnergyTrace implicit = UndampedEnergy(Integrator::kImplicitEuler, 0.01, kSteps);
  EXPECT_LT(implicit.last / implicit.first, 1e-3);  // (1 + (ωh)²)^−n = e^−10
}

// The largest step (ω = 1) for which 2000 steps stay bounded, by bisection.
double StableStepLimit(Integrator integrator) {
  double lo = 0.5, hi = 5.0;
  for (int it = 0; it < 40; ++it) {
    const double h = 0.5 * (lo + hi);
    MassSpringModel model = Oscillator(integrator, 1.0, 0.0, 1.0, 1e-3);
    bool bounded = true;
    for (int i = 0; i < 2000 && bounded; ++i) {
      bounded = model.Step(h) && std::abs(model.positions()[1].x() - kRest) < 1e-1;
    }
    (bounded ? lo : hi) = h;
  }
  return lo;
}

TEST(MassSpringTest, MeasuredStableStepsMatchTheory) {
  EXPECT_NEAR(StableStepLimit(Integrator::kSymplecticEuler), 2.0, 0.05 * 2.0);
  EXPECT_NEAR(StableStepLimit(Integrator::kRk4), 2 * std::sqrt(2.0), 0.05 * 2 * std::sqrt(2.0));
}

// A 66-particle sphere, bottom fixed.
// The sphere's lower cap (z < −3 cm) fixed, stepped with `sp`.
MassSpringModel SphereStepped(const MassSpringStepParams& sp, double stiffness, int levels = 2,
                              VolumeMode volume = VolumeMode::kNone, double damping = 0.02) {
  auto mesh = geometry::MakeSubdividedSphere(
      {0.05, levels, geometry::SphereBase::kOctahedron, Vec3::Zero()});
  MassSpringBuildParams bp;
  bp.total_mass = 0.5;
  bp.structural_stiffness = stiffness;
  bp.bending_stiffness = 0.1 * stiffness;
  bp.volume_stiffness = stiffness;
  bp.damping = damping;
  bp.volume = volume;
  auto sys = BuildMassSpring(*mesh, bp);
  EXPECT_TRUE(sys.ok());
  auto model = MassSpringModel::Create(*sys, sp);
  EXPECT_TRUE(model.ok());
  for (int i = 0; i < static_cast<int>(sys->rest_positions.size()); ++i) {
    if (sys->rest_positions[i].z() < -0.03) model->SetFixed(i, true);
  }
  return *model;
}

MassSpringModel Sphere(Integrator integrator, double stiffness, int levels = 2,
                       VolumeMode volume = VolumeMode::kNone, double damping = 0.02) {
  MassSpringStepParams sp;
  sp.integrator = integrator;
  return SphereStepped(sp, stiffness, levels, volume, damping);
}

// On a mesh, the symplectic Euler limit is 2/ω_max, ω_max² the largest eigenvalue of M⁻¹K.
// The implicit step leaves out a spring whose ends are both fixed or driven (it adds only to rows
// the solve filters to zero): a stretched one there changes nothing, until one of its ends is
// set free, when it must pull again.
TEST(MassSpringTest, ImplicitStepIgnoresSpringsBetweenFixedParticlesUntilOneIsFreed) {
  auto chain = [](bool with_fixed_spring) {
    MassSpringSystem s;
    s.rest_positions = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.2, 0, 0), Vec3(0.3, 0, 0)};
    s.masses = {0.01, 0.01, 0.01, 0.01};
    s.springs = {{1, 2, 50.0, 0.05, 0.1}, {2, 3, 50.0, 0.05, 0.1}};
    // Between the two fixed particles, stretched to twice its rest length.
    if (with_fixed_spring) s.springs.push_back({0, 1, 80.0, 0.05, 0.05});
    MassSpringStepParams p;
    p.integrator = Integrator::kImplicitEuler;
    p.gravity = Vec3(0, -9.81, 0);
    p.cg_tolerance = 1e-9;
    auto model = MassSpringModel::Create(s, p);
    EXPECT_TRUE(model.ok());
    model->SetFixed(0, true);
    model->SetFixed(1, true);
    return *model;
  };
  MassSpringModel with = chain(true), without = chain(false);
  for (int k = 0; k < 200; ++k) with.Step(1e-3), without.Step(1e-3);
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 3; ++c)
      EXPECT_DOUBLE_EQ(with.positions()[i][c], without.positions()[i][c]) << i << " " << c;
  EXPECT_LT(with.positions()[3].y(), -1e-3);  // the free end did fall

  // Particle 1 set free: the stretched spring pulls it toward particle 0 only where it exists.
  with.SetFixed(1, false), without.SetFixed(1, false);
  for (int k = 0; k < 50; ++k) with.Step(1e-3), without.Step(1e-3);
  EXPECT_LT(with.positions()[1].x(), without.positions()[1].x() - 1e-3);
}

TEST(MassSpringTest, SymplecticStepLimitOnAMeshIsTwoOverTheLargestFrequency) {
  const double omega = Sphere(Integrator::kSymplecticEuler, 50.0).MaxAngularFrequency(500);
  ASSERT_GT(omega, 0);
  double lo = 0.2 / omega, hi = 5.0 / omega;
  for (int it = 0; it < 30; ++it) {
    const double h = 0.5 * (lo + hi);
    MassSpringModel model = Sphere(Integrator::kSymplecticEuler, 50.0);
    for (int i = 0; i < model.system().surface_particles; ++i) {
      model.SetExternalForce(i, Vec3(std::sin(i), std::cos(3.0 * i), std::sin(7.0 * i)) * 1e-4);
    }
    model.Step(h);
    model.ClearExternalForces();
    bool bounded = true;
    for (int i = 0; i < 3000 && bounded; ++i)
      bounded = model.Step(h) && model.MaxDisplacement() < 1e-2;
    (bounded ? lo : hi) = h;
  }
  EXPECT_NEAR(lo * omega, 2.0, 0.1);
}

TEST(MassSpringTest, ImplicitEulerStaysBoundedFarBeyondTheExplicitLimitOnStiffSprings) {
  MassSpringModel probe = Sphere(Integrator::kImplicitEuler, 1e5);
  const double h = 100 * 2.0 / probe.MaxAngularFrequency(500);  // 100× the explicit limit
  for (Integrator integrator : {Integrator::kImplicitEuler, Integrator::kSymplecticEuler}) {
    MassSpringModel model = Sphere(integrator, 1e5);
    const int top = 4;  // the +z pole of the octahedron
    ASSERT_GT(model.system().rest_positions[top].z(), 0.049);
    model.SetExternalForce(top, Vec3(0, 0, -5.0));
    bool ok = true;
    for (int i = 0; i < 200 && ok; ++i) ok = model.Step(h);
    if (integrator == Integrator::kImplicitEuler) {
      EXPECT_TRUE(ok);
      EXPECT_FALSE(model.diverged());
      EXPECT_LT(model.MaxDisplacement(), 0.01);  // 5 N on 1e5 N/m springs: sub-millimetre
    } else {
      // The explicit method diverges, and says so instead of returning NaN.
      EXPECT_FALSE(ok);
      EXPECT_TRUE(model.diverged());
      for (const Vec3& x : model.positions()) EXPECT_TRUE(x.allFinite());
    }
  }
}

// A tissue settled under gravity: its net force vanishes, so a test relative to it alone asks for
// rounding. The energy floor ends each solve in a few iterations instead, and the settled state
// is the exact solve's within a micrometre, at rest.
TEST(MassSpringTest, ASettledTissueSolvesInAFewIterationsAndStaysWhereTheExactSolveIs) {
  MassSpringStepParams floored, exact;
  floored.integrator = exact.integrator = Integrator::kImplicitEuler;
  floored.gravity = exact.gravity = Vec3(0, 0, -9.81);
  exact.cg_energy_floor = 0;
  MassSpringModel a = SphereStepped(floored, 2450, 3, VolumeMode::kNone, 12.25 / 258);
  MassSpringModel b = SphereStepped(exact, 2450, 3, VolumeMode::kNone, 12.25 / 258);
  for (int k = 0; k < 2000; ++k) ASSERT_TRUE(a.Step(1e-3) && b.Step(1e-3)) << k;
  long its_a = 0, its_b = 0;
  for (int k = 0; k < 200; ++k) {
    ASSERT_TRUE(a.Step(1e-3) && b.Step(1e-3)) << k;
    its_a += a.last_cg_iterations(), its_b += b.last_cg_iterations();
  }
  EXPECT_LE(its_a, 3 * 200) << "a few iterations a step once settled";
  EXPECT_GT(its_b, 2 * its_a) << "the exact solve chases rounding";
  EXPECT_GT(a.MaxDisplacement(), 1e-4) << "gravity sagged the sphere";
  for (size_t i = 0; i < a.positions().size(); ++i)
    EXPECT_LT((a.positions()[i] - b.positions()[i]).norm(), 1e-6) << i;
  EXPECT_LT(a.KineticEnergy(), 1e-10);
}

// A tool's coupling: the anchored particle is pulled to the target, and two anchors on one
// particle act as one with their summed stiffness and damping (the implicit step adds both to
// the particle's diagonal before it takes the reciprocal, once).
TEST(MassSpringTest, AnchorsPullTheirParticleAndTwoOnOneActAsTheirSum) {
  MassSpringStepParams sp;
  sp.integrator = Integrator::kImplicitEuler;
  sp.cg_tolerance = 1e-10;  // both solves converged: equal to rounding, not to the tolerance
  sp.cg_energy_floor = 0;
  MassSpringModel one = SphereStepped(sp, 1e3);
  MassSpringModel two = SphereStepped(sp, 1e3);
  const int top = 4;  // the +z pole of the octahedron
  const Vec3 rest = one.system().rest_positions[top];
  const Vec3 target = rest + Vec3(0.004, 0, -0.006);
  one.SetAnchor(top, target, 200.0, 1.0);
  two.SetAnchor(top, target, 120.0, 0.6);
  two.SetAnchor(top, target, 80.0, 0.4);
  long iterations_one = 0, iterations_two = 0;  // equal too: the same preconditioner
  for (int k = 0; k < 400; ++k) {
    ASSERT_TRUE(one.Step(1e-3));
    ASSERT_TRUE(two.Step(1e-3));
    iterations_one += one.last_cg_iterations(), iterations_two += two.last_cg_iterations();
  }
  EXPECT_EQ(iterations_one, iterations_two);
  for (size_t i = 0; i < one.positions().size(); ++i)
    EXPECT_LT((one.positions()[i] - two.positions()[i]).norm(), 1e-9) << i;
  // Pulled most of the way against the sphere's springs.
  EXPECT_LT((one.positions()[top] - target).norm(), 0.5 * (rest - target).norm());
  EXPECT_GT(one.InternalForceOn(top).norm(), 0.1) << "the tissue pulls back";
}

// The implicit step is stable, but a force no tissue meets can still throw a particle beyond
// divergence_distance (1 m): the step's own last pass notices, as CheckFinite did, for a free
// particle and for a driven one.
TEST(MassSpringTest, AnImplicitStepBeyondTheDivergenceDistanceIsReportedAndReset) {
  for (const bool driven : {false, true}) {
    MassSpringModel model = Sphere(Integrator::kImplicitEuler, 1e3);
    const int top = 4;  // the +z pole of the octahedron
    ASSERT_TRUE(model.Step(1e-3));
    if (driven) {
      model.SetKinematic(top, true);
      model.SetKinematicTarget(top, Vec3(0, 0, 2.0));  // 1.95 m from rest
    } else {
      model.SetExternalForce(top, Vec3(0, 0, 1e9));
    }
    EXPECT_FALSE(model.Step(1e-3)) << driven;
    EXPECT_TRUE(model.diverged());
    for (size_t i = 0; i < model.positions().size(); ++i)
      EXPECT_EQ(model.positions()[i], model.system().rest_positions[i]) << "reset to rest";
    EXPECT_FALSE(model.Step(1e-3));  // stays stopped until reset
    model.Reset();
    model.ClearExternalForces();
    if (driven) model.SetKinematic(top, false);
    EXPECT_TRUE(model.Step(1e-3));
  }
}

// The implicit step keeps x and v in four-lane copies from one step to the next. After anything
// else changes them (a reset, a step of another integrator, a change of role, which zeroes the
// particle's velocity), the next implicit step must start from the new x and v: as two twins do
// whose copies were dropped by means that change no state (beyond 1e-297 m/s), each by another
// one: a symplectic step of 1e-300 s, and fixing a particle that is fixed already. The solve is
// tight, so the twins differ from the model only by their preconditioner's age.
TEST(MassSpringTest, AnImplicitStepStartsFromTheStateAnythingElseLeft) {
  MassSpringStepParams sp;
  sp.integrator = Integrator::kImplicitEuler;
  sp.cg_tolerance = 1e-12;
  sp.cg_energy_floor = 0;
  MassSpringModel model = SphereStepped(sp, 50);
  const double h = 1e-3;
  const int top = 4, low = 5;  // the octahedron's +z and −z poles (the second fixed)
  int other_fixed = -1;        // one more fixed particle, the second twin's
  for (size_t i = 0; i < model.positions().size(); ++i)
    if (model.system().rest_positions[i].z() < -0.03 && i != low) other_fixed = static_cast<int>(i);
  ASSERT_GE(other_fixed, 0);
  ASSERT_TRUE(model.Step(h));
  auto implicit_step_matches_fresh_twins = [&](const char* after) {
    MassSpringModel stepped = model, fixed = model;
    stepped.SetIntegrator(Integrator::kSymplecticEuler);
    ASSERT_TRUE(stepped.Step(1e-300));
    stepped.SetIntegrator(Integrator::kImplicitEuler);
    fixed.SetFixed(other_fixed, true);
    const std::vector<Vec3> x0 = model.positions();
    ASSERT_TRUE(model.Step(h)) << after;
    double largest = 0;
    for (MassSpringModel* twin : {&stepped, &fixed}) {
      ASSERT_TRUE(twin->Step(h)) << after;
      for (size_t i = 0; i < x0.size(); ++i) {
        EXPECT_LT((model.positions()[i] - twin->positions()[i]).norm(), 1e-12)
            << after << ", particle " << i;
        EXPECT_LT((model.velocities()[i] - twin->velocities()[i]).norm(), 1e-9)
            << after << ", particle " << i;
        largest = std::max(largest, (model.positions()[i] - x0[i]).norm());
      }
    }
    EXPECT_GT(largest, 1e-7) << after << ": nothing moved";
  };
  model.SetExternalForce(top, Vec3(0, 0, 0.5));
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(model.Step(h));
  implicit_step_matches_fresh_twins("implicit steps");
  model.Reset();
  implicit_step_matches_fresh_twins("a reset");
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(model.Step(h));
  model.SetIntegrator(Integrator::kSymplecticEuler);
  ASSERT_TRUE(model.Step(h / 10));
  model.SetIntegrator(Integrator::kImplicitEuler);
  implicit_step_matches_fresh_twins("a symplectic step");
  model.SetKinematic(top, true);  // driven down 0.4 mm per step, released while moving
  for (int k = 0; k < 5; ++k) {
    model.SetKinematicTarget(top, model.positions()[top] - Vec3(0, 0, 0.0004));
    ASSERT_TRUE(model.Step(h));
  }
  model.SetKinematic(top, false);  // released: v zeroed, the copies still hold the driven v
  implicit_step_matches_fresh_twins("a driven particle set free");
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(model.Step(h));
  model.SetFixed(top, true);  // stopped while moving
  model.SetFixed(top, false);
  implicit_step_matches_fresh_twins("a moving particle fixed and set free");
  model.SetFixed(low, false);
  implicit_step_matches_fresh_twins("a fixed particle set free");
}

TEST(MassSpringTest, CoincidentParticlesAndZeroLengthSpringsGiveNoNan) {
  for (Integrator integrator : kAllIntegrators) {
    MassSpringSystem s;
    s.rest_positions = {Vec3::Zero(), Vec3::Zero(), Vec3(0.01, 0, 0), Vec3(0.01, 0, 0)};
    s.masses = {0.01, 0.01, 0.01, 0.01};
    s.springs = {{0, 1, 10, 0.1, 0.0},    // zero length between coincident particles
                 {2, 3, 10, 0.1, 0.005},  // coincident particles that want to be apart
                 {1, 2, 10, 0.1, 0.01}};
    MassSpringStepParams p;
    p.integrator = integrator;
    auto model = MassSpringModel::Create(s, p);
    ASSERT_TRUE(model.ok());
    model->SetExternalForce(0, Vec3(0.001, 0, 0));
    for (int i = 0; i < 100; ++i) ASSERT_TRUE(model->Step(1e-3)) << IntegratorName(integrator);
    for (const Vec3& x : model->positions())
      EXPECT_TRUE(x.allFinite()) << IntegratorName(integrator);
    EXPECT_TRUE(std::isfinite(model->PotentialEnergy()));
  }
}

TEST(MassSpringTest, BadMassesStiffnessAndSpringsAreRejectedByName) {
  MassSpringSystem good;
  good.rest_positions = {Vec3::Zero(), Vec3(0.01, 0, 0)};
  good.masses = {0.1, 0.1};
  good.springs = {{0, 1, 10, 0.1, 0.01}};
  ASSERT_TRUE(MassSpringModel::Create(good, {}).ok());
  auto expect_error = [&](MassSpringSystem s, const std::string& field, const std::string& text) {
    auto m = MassSpringModel::Create(s, {});
    ASSERT_FALSE(m.ok()) << text;
    EXPECT_EQ(m.error().field, field);
    EXPECT_NE(m.error().message.find(text), std::string::npos) << m.error().message;
  };
  MassSpringSystem s = good;
  s.masses[1] = 0;
  expect_error(s, "masses", "particle 1 mass must be finite and > 0");
  s.masses[1] = -1;
  expect_error(s, "masses", "particle 1 mass");
  s = good;
  s.springs[0].stiffness = 0;
  expect_error(s, "springs", "spring 0 stiffness must be finite and > 0");
  s.springs[0].stiffness = -5;
  expect_error(s, "springs", "spring 0 stiffness");
  s = good;
  s.springs[0].damping = -0.1;
  expect_error(s, "springs", "spring 0 damping");
  s = good;
  s.springs[0].j = 0;
  expect_error(s, "springs", "two distinct particles");
  s = good;
  s.springs[0].j = 7;
  expect_error(s, "springs", "two distinct particles");
  s = good;
  s.masses.pop_back();
  expect_error(s, "masses", "one mass per particle");
  MassSpringBuildParams bp;
  bp.structural_stiffness = -1;
  auto mesh = geometry::MakeSubdividedSphere({});
  EXPECT_EQ(BuildMassSpring(*mesh, bp).error().field, "structural_stiffness");
  bp = {};
  bp.total_mass = 0;
  EXPECT_EQ(BuildMassSpring(*mesh, bp).error().field, "total_mass");
}

TEST(MassSpringTest, DivergenceIsDetectedReportedAndLeavesAFiniteState) {
  MassSpringModel model = Oscillator(Integrator::kExplicitEuler, 1e4, 0.0, 1e-3, 0.01);
  bool ok = true;
  int steps = 0;
  while (ok && steps < 1000) ok = model.Step(0.05), ++steps;  // ω·h ≈ 158
  EXPECT_FALSE(ok);
  EXPECT_TRUE(model.diverged());
  for (const Vec3& x : model.positions()) EXPECT_TRUE(x.allFinite());
  EXPECT_FALSE(model.Step(1e-6));  // stays stopped until reset
  model.Reset();
  EXPECT_FALSE(model.diverged());
  EXPECT_TRUE(model.Step(1e-6));
}

TEST(MassSpringTest, SpringBuildCountsMatchTheMeshTopology) {
  auto mesh =
      geometry::MakeSubdividedSphere({0.05, 3, geometry::SphereBase::kOctahedron, Vec3::Zero()});
  const int v = mesh->VertexCount(), e = static_cast<int>(geometry::UniqueEdges(*mesh).size());
  MassSpringBuildParams bp;
  auto sys = BuildMassSpring(*mesh, bp);
  ASSERT_TRUE(sys.ok());
  EXPECT_EQ(static_cast<int>(sys->springs.size()), 2 * e);  // structural + one bending per edge
  bp.volume = VolumeMode::kInnerLayer;
  auto layered = BuildMassSpring(*mesh, bp);
  ASSERT_TRUE(layered.ok());
  EXPECT_EQ(static_cast<int>(layered->rest_positions.size()), 2 * v);
  EXPECT_EQ(static_cast<int>(layered->springs.size()), 2 * e + 3 * e + v);
  double mass = 0;
  for (double m : layered->masses) mass += m;
  EXPECT_NEAR(mass, bp.total_mass, 1e-12);
  for (const Spring& s : layered->springs) {
    EXPECT_NEAR(s.rest_length, (layered->rest_positions[s.j] - layered->rest_positions[s.i]).norm(),
                1e-15);
  }
}

TEST(MassSpringTest, TetMeshEdgesBecomeSpringsWithLumpedMass) {
  // A unit cube split into five tetrahedra.
  geometry::TetMesh cube;
  for (int i = 0; i < 8; ++i) cube.positions.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  cube.tetrahedra = {{0, 1, 2, 4}, {1, 3, 2, 7}, {1, 2, 4, 7}, {2, 4, 7, 6}, {1, 4, 5, 7}};
  for (int t = 0; t < cube.TetCount(); ++t) {
    if (geometry::TetVolume(cube, t) < 0) std::swap(cube.tetrahedra[t][2], cube.tetrahedra[t][3]);
  }
  auto sys = BuildMassSpring(cube, 1000.0, 100.0, 0.1);
  ASSERT_TRUE(sys.ok()) << sys.error().message;
  EXPECT_EQ(sys->springs.size(), 18u);  // 12 cube edges + 6 face diagonals
  double mass = 0;
  for (double m : sys->masses) mass += m;
  EXPECT_NEAR(mass, 1000.0, 1e-9);
}

// Newton's third law: at equilibrium the tool's push on the pressed particle is carried by the
// fixed base, and the reaction the tool feels points back out of the tissue.
TEST(MassSpringTest, PressedSphereSettlesWithTheToolForceCarriedByTheBase) {
  MassSpringModel model = Sphere(Integrator::kImplicitEuler, 50.0, 3, VolumeMode::kNone, 0.5);
  const int top = 4;
  const Vec3 rest = model.system().rest_positions[top];
  model.SetKinematic(top, true);
  // 6 s: the slowest mode creeps for seconds after the kinetic energy is gone (at 2 s the tool's
  // force is still 55% above its final value, and the balance holds only to rounding luck).
  for (int i = 1; i <= 6000; ++i) {
    model.SetKinematicTarget(top, rest - Vec3(0, 0, 0.005 * std::min(1.0, i / 500.0)));
    ASSERT_TRUE(model.Step(1e-3));
  }
  EXPECT_LT(model.KineticEnergy(), 1e-9);
  const Vec3 on_top = model.InternalForceOn(top);
  EXPECT_GT(on_top.z(), 1e-3);  // the tissue pushes the tool back up
  Vec3 base = Vec3::Zero();
  for (int i = 0; i < static_cast<int>(model.positions().size()); ++i) {
    if (model.system().rest_positions[i].z() < -0.03) base += model.InternalForceOn(i);
  }
  EXPECT_NEAR((on_top + base).norm(), 0.0, 1e-3 * on_top.norm());
  EXPECT_NEAR((model.positions()[top] - rest).norm(), 0.005, 1e-12);
}

TEST(MassSpringTest, InnerLayerKeepsMoreVolumeUnderTheSamePress) {
  double loss[2];
  for (int k = 0; k < 2; ++k) {
    MassSpringModel model = Sphere(Integrator::kImplicitEuler, 50.0, 3,
                                   k ? VolumeMode::kInnerLayer : VolumeMode::kNone);
    model.SetExternalForce(4, Vec3(0, 0, -0.5));
    for (int i = 0; i < 3000; ++i) ASSERT_TRUE(model.Step(1e-3));
    auto mesh =
        geometry::MakeSubdividedSphere({0.05, 3, geometry::SphereBase::kOctahedron, Vec3::Zero()});
    const double v0 = geometry::SignedVolume(*mesh);
    mesh->positions.assign(model.positions().begin(),
                           model.positions().begin() + mesh->VertexCount());
    loss[k] = (v0 - geometry::SignedVolume(*mesh)) / v0;
  }
  EXPECT_GT(loss[0], 0.0);
  EXPECT_LT(loss[1], 0.5 * loss[0]);
}

TEST(MassSpringTest, SubstepsEqualSmallerSteps) {
  MassSpringModel a = Sphere(Integrator::kMidpoint, 50.0), b = Sphere(Integrator::kMidpoint, 50.0);
  a.SetExternalForce(4, Vec3(0, 0, -0.1));
  b.SetExternalForce(4, Vec3(0, 0, -0.1));
  for (int i = 0; i < 10; ++i) a.Step(4e-3, 4);
  for (int i = 0; i < 40; ++i) b.Step(1e-3);
  for (size_t i = 0; i < a.positions().size(); ++i) EXPECT_EQ(a.positions()[i], b.positions()[i]);
}

TEST(MassSpringTest, AHangingMassSettlesAtWeightOverStiffness) {
  MassSpringSystem s;
  s.rest_positions = {Vec3::Zero(), Vec3(0, 0, -0.1)};
  s.masses = {1.0, 0.2};
  s.springs = {{0, 1, 40.0, 2.0, 0.1}};
  MassSpringStepParams p;
  p.integrator = Integrator::kImplicitEuler;
  p.gravity = Vec3(0, 0, -9.81);
  p.cg_energy_floor = 0;  // the equilibrium to 1e-9 m, past what a settled tissue's solve asks
  auto model = MassSpringModel::Create(s, p);
  ASSERT_TRUE(model.ok());
  model->SetFixed(0, true);
  for (int i = 0; i < 5000; ++i) ASSERT_TRUE(model->Step(1e-3));
  EXPECT_NEAR(model->positions()[1].z(), -0.1 - 0.2 * 9.81 / 40.0, 1e-9);  // x = mg/k
  // Potential energy: spring ½kx² minus the work gravity did, −mgx: total −½ (mg)²/k.
  EXPECT_NEAR(model->PotentialEnergy(), -0.5 * std::pow(0.2 * 9.81, 2) / 40.0, 1e-9);
}

TEST(MassSpringTest, IntegratorNamesRoundTrip) {
  for (Integrator i : kAllIntegrators) EXPECT_EQ(*ParseIntegrator(IntegratorName(i)), i);
  auto bad = ParseIntegrator("leapfrog");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("implicit-euler"), std::string::npos);
}

// The implicit solve starts from an extrapolation of the last steps' Δv whose degree (1 to 3)
// follows how well each degree guessed the last step. On a smooth drive at a tight tolerance the
// higher degrees start closer and the solve needs fewer CG iterations; through a jolt (a force
// switched on at once) no degree guesses well, and the solve still ends at the same state.
TEST(MassSpringTest, ImplicitFirstGuessDegreeFollowsTheDriveAndLeavesTheSolutionUnchanged) {
  auto make = [](int most) {
    MassSpringStepParams sp;
    sp.integrator = Integrator::kImplicitEuler;
    sp.cg_tolerance = 1e-6;
    sp.cg_energy_floor = 0;
    sp.cg_extrapolation = most;
    return SphereStepped(sp, 200.0, 3, VolumeMode::kNone, 0.05);  // bending springs 20 N/m
  };
  MassSpringModel linear = make(1), adaptive = make(3);
  const MassSpringSystem& sys = linear.system();
  const double h = 2e-4;
  long its_linear = 0, its_adaptive = 0;
  int higher = 0;
  // 0.2 s of a smooth sideways push on the top cap (a 5 Hz sine), then a jolt: 1 N down at once.
  for (int k = 0; k < 1200; ++k) {
    const double t = k * h;
    for (int i = 0; i < static_cast<int>(sys.rest_positions.size()); ++i) {
      if (sys.rest_positions[i].z() < 0.045) continue;
      const Vec3 f =
          k < 1000 ? Vec3(0.05 * std::sin(2 * std::numbers::pi * 5 * t), 0, 0) : Vec3(0, 0, -1.0);
      linear.SetExternalForce(i, f), adaptive.SetExternalForce(i, f);
    }
    ASSERT_TRUE(linear.Step(h) && adaptive.Step(h)) << k;
    EXPECT_EQ(linear.last_extrapolation(), 1);
    if (k >= 100 && k < 1000) {
      its_linear += linear.last_cg_iterations(), its_adaptive += adaptive.last_cg_iterations();
      higher += adaptive.last_extrapolation() > 1;
    }
  }
  EXPECT_GT(higher, 800) << higher;  // most smooth steps take a higher degree
  EXPECT_LT(its_adaptive, 0.8 * its_linear) << its_adaptive << " vs " << its_linear;
  // Both solved every step to 1e-6: the states agree far below a micrometre after the jolt.
  EXPECT_GT(linear.MaxDisplacement(), 1e-3);
  for (size_t i = 0; i < linear.positions().size(); ++i)
    EXPECT_LT((linear.positions()[i] - adaptive.positions()[i]).norm(), 1e-8) << i;
  // Reset forgets the history: the next step starts from the linear guess of zeros.
  adaptive.Reset();
  ASSERT_TRUE(adaptive.Step(h));
  EXPECT_EQ(adaptive.last_extrapolation(), 1);

  for (int most : {0, 4}) {
    MassSpringStepParams sp;
    sp.integrator = Integrator::kImplicitEuler;
    sp.cg_extrapolation = most;
    auto bad = MassSpringModel::Create(sys, sp);
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.error().message.find("1 to 3"), std::string::npos) << bad.error().message;
  }
}

}  // namespace
}  // namespace vsurg::tissue

namespace vsurg::tissue {
namespace {

// A particle split in two (a cut): each copy takes the springs moved to it, the two ends then move
// apart under their own springs, and no copy is made beyond the room reserved.
TEST(MassSpringTopologyTest, ASplitParticleSeparatesItsSpringsWithinTheRoomReserved) {
  MassSpringSystem s;
  s.rest_positions = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.2, 0, 0)};
  s.masses = {1.0, 1.0, 1.0};
  s.springs = {{0, 1, 100, 0.1, 0.05}, {1, 2, 100, 0.1, 0.05}};  // stretched: rest 0.05 m
  MassSpringStepParams p;
  p.integrator = Integrator::kImplicitEuler;
  auto m = MassSpringModel::Create(s, p);
  ASSERT_TRUE(m.ok());
  m->SetFixed(0, true), m->SetFixed(2, true);
  m->ReserveParticles(4);
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(m->Step(1e-3));
  EXPECT_NEAR(m->positions()[1].x(), 0.1, 1e-9) << "balanced between its two springs";
  const int copy = m->SplitParticle(1, 0.5);
  ASSERT_EQ(copy, 3);
  m->SetMass(1, 0.5);
  size_t right = 0;
  for (size_t k = 0; k < m->system().springs.size(); ++k)
    if (m->system().springs[k].j == 2 || m->system().springs[k].i == 2) right = k;
  m->SetSpring(right, copy, 2, 0.05);
  EXPECT_EQ(m->SplitParticle(1, 0.5), -1) << "beyond the room reserved";
  EXPECT_EQ(m->SplitParticle(1, 0.0), -1) << "a mass must be > 0";
  for (int i = 0; i < 3000; ++i) ASSERT_TRUE(m->Step(1e-3));
  // Each half is pulled to its own fixed end's rest length: the cut opens.
  EXPECT_NEAR(m->positions()[1].x(), 0.05, 1e-4);
  EXPECT_NEAR(m->positions()[copy].x(), 0.15, 1e-4);
}

}  // namespace
}  // namespace vsurg::tissue
