// The neo-Hookean reference (common/tissue/hyperelastic.h): its invariants (nothing at rest or
// under a rigid rotation, forces the energy's exact gradient, the tangent the forces' exact
// derivative), uniaxial stretch and compression against the closed form of a compressible
// neo-Hookean bar, near incompressibility, an element pushed inside out, and the refusals.
#include "common/tissue/hyperelastic.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <initializer_list>
#include <numeric>
#include <random>

#include "common/geometry/tet_generators.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

geometry::TetCylinder NeoHookeanBar() {
  geometry::TetCylinderParams p;
  p.length = 0.1;
  p.radius_base = p.radius_tip = 0.02;
  p.rings = 2;
  p.layers = 6;
  return geometry::MakeTetCylinder(p).value();
}

// The lateral stretch λ2 of a traction-free bar stretched λ1 along its axis, F = diag(λ1, λ2, λ2):
// with I1 = λ1² + 2λ2², e = e^{b(I1−3)} (1 for neo-Hookean) and J = λ1·λ2², the lateral stress
// μ·e·λ2 − μ/λ2 + λ·ln J/λ2 vanishes (solved by secant steps on λ2); then the nominal axial
// stress is μ·e·λ1 − μ/λ1 + λ·ln J/λ1.
std::pair<double, double> UniaxialClosedForm(double mu, double lambda, double b, double l1) {
  auto stress = [&](double stretch, double l2) {
    const double i1 = l1 * l1 + 2 * l2 * l2, j = l1 * l2 * l2;
    const double e = b > 0 ? std::exp(b * (i1 - 3)) : 1.0;
    return mu * e * stretch - mu / stretch + lambda * std::log(j) / stretch;
  };
  double a = 1.0, c = 0.9;
  for (int it = 0; it < 200 && std::abs(c - a) > 1e-15; ++it) {
    const double fa = stress(a, a), fc = stress(c, c);
    const double next = c - fc * (c - a) / (fc - fa);
    a = c;
    c = next;
  }
  return {c, stress(l1, c)};
}

// At state x: the tangent symmetric, and for each listed coordinate the force the central
// difference of the energy and the tangent's column the central difference of the forces (step h,
// m). Leaves the model at x.
void ExpectExactDerivatives(HyperelasticFem& fem, const std::vector<Vec3>& x,
                            std::initializer_list<int> dofs, double h) {
  fem.SetPositions(x);
  const Eigen::VectorXd f = fem.InternalForces();
  const Eigen::MatrixXd k(fem.Tangent());
  EXPECT_LT((k - k.transpose()).lpNorm<Eigen::Infinity>(), 1e-9 * k.lpNorm<Eigen::Infinity>());
  for (int dof : dofs) {
    std::vector<Vec3> plus = x, minus = x;
    plus[dof / 3][dof % 3] += h;
    minus[dof / 3][dof % 3] -= h;
    fem.SetPositions(plus);
    const double e_plus = fem.StrainEnergy();
    const Eigen::VectorXd f_plus = fem.InternalForces();
    fem.SetPositions(minus);
    const double e_minus = fem.StrainEnergy();
    const Eigen::VectorXd f_minus = fem.InternalForces();
    EXPECT_NEAR(-(e_plus - e_minus) / (2 * h), f[dof], 1e-6 * f.lpNorm<Eigen::Infinity>()) << dof;
    const Eigen::VectorXd column = -(f_plus - f_minus) / (2 * h);
    EXPECT_LT((column - k.col(dof)).lpNorm<Eigen::Infinity>(), 1e-5 * k.lpNorm<Eigen::Infinity>())
        << dof;
  }
  fem.SetPositions(x);
}

TEST(HyperelasticTest, RestAndRigidRotationsHoldNoEnergyAndNoForce) {
  for (bool nodal : {false, true}) {
    SCOPED_TRACE(nodal ? "the volume at the vertices" : "the volume per element");
    const auto bar = NeoHookeanBar();
    auto fem = HyperelasticFem::Create(bar.mesh, {30e3, 0.45, 0, nodal});
    ASSERT_TRUE(fem.ok()) << fem.error().message;
    EXPECT_NEAR(fem->StrainEnergy(), 0, 1e-15);
    EXPECT_LT(fem->InternalForces().lpNorm<Eigen::Infinity>(), 1e-12);
    const Eigen::Matrix3d rot =
        Eigen::AngleAxisd(1.1, Vec3(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
    std::vector<Vec3> x;
    for (const Vec3& p : bar.mesh.positions) x.push_back(rot * p + Vec3(0.2, -0.1, 0.05));
    fem->SetPositions(x);
    EXPECT_NEAR(fem->StrainEnergy(), 0, 1e-12);
    EXPECT_LT(fem->InternalForces().lpNorm<Eigen::Infinity>(), 1e-9);  // N, at 30 kPa
  }
}

// A large random deformation: forces against central differences of the energy, the tangent
// against central differences of the forces, and its symmetry.
TEST(HyperelasticTest, ForcesAndTangentAreTheEnergysExactDerivatives) {
  for (const auto& [b, nodal] : {std::pair{0.0, false}, {2.0, false}, {0.0, true}, {2.0, true}}) {
    SCOPED_TRACE("b " + std::to_string(b) + (nodal ? ", the volume at the vertices" : ""));
    const auto bar = NeoHookeanBar();
    auto fem = HyperelasticFem::Create(bar.mesh, {30e3, 0.45, b, nodal}).value();
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0, 1.5e-3);  // m, against 5–10 mm elements
    std::vector<Vec3> x;
    for (const Vec3& p : bar.mesh.positions)
      x.push_back(Vec3(1.2 * p.x(), 0.9 * p.y(), 1.3 * p.z()) +
                  Vec3(noise(rng), noise(rng), noise(rng)));
    fem.SetPositions(x);
    ASSERT_TRUE(std::isfinite(fem.StrainEnergy()));
    ExpectExactDerivatives(fem, x, {0, 7, 40, 3 * bar.mesh.VertexCount() - 1}, 1e-7);
  }
}

// The exponential law stiffens: the same small-strain stiffness as the neo-Hookean one (b → 0),
// more stress at a large stretch, and the more the larger b.
TEST(HyperelasticTest, TheExponentialLawStiffensAsTheTissueStretches) {
  const double mu = 10e3, lambda = 90e3;
  const auto small_nh = UniaxialClosedForm(mu, lambda, 0, 1.00001).second;
  const auto small_exp = UniaxialClosedForm(mu, lambda, 2, 1.00001).second;
  EXPECT_NEAR(small_exp / small_nh, 1.0, 0.01);
  const double large_nh = UniaxialClosedForm(mu, lambda, 0, 1.5).second;
  const double large_2 = UniaxialClosedForm(mu, lambda, 2, 1.5).second;
  const double large_5 = UniaxialClosedForm(mu, lambda, 5, 1.5).second;
  EXPECT_GT(large_2, 1.5 * large_nh);
  EXPECT_GT(large_5, large_2);
}

// The bar held on rollers at its base (z = 0), its end moved to λ1·L, the rigid motions held by
// the base's centre (x, y) and one more base vertex (y): the deformation is homogeneous, which
// linear tetrahedra represent exactly, so the solve meets the closed form to its tolerance; from
// a first guess stretched along the axis, Newton finds the lateral contraction.
TEST(HyperelasticTest, UniaxialStretchAndCompressionMeetTheClosedForm) {
  for (bool nodal : {false, true})  // a uniform state: the volume at the vertices is the same
    for (double b : {0.0, 2.0})
      for (double nu : {0.3, 0.45, 0.49}) {
        for (double l1 : {1.5, 1.1, 0.7}) {
          SCOPED_TRACE("b " + std::to_string(b) + " nu " + std::to_string(nu) + " stretch " +
                       std::to_string(l1) + (nodal ? ", the volume at the vertices" : ""));
          const auto bar = NeoHookeanBar();
          auto fem = HyperelasticFem::Create(bar.mesh, {30e3, nu, b, nodal}).value();
          // The first guess: stretched along the axis alone (the end's move spread over the bar).
          std::vector<Vec3> guess = bar.mesh.positions;
          for (Vec3& p : guess) p.z() *= l1;
          fem.SetPositions(guess);
          int centre = -1, on_x = -1;
          for (int v : bar.base) {
            const Vec3& p = bar.mesh.positions[v];
            if (p.head<2>().norm() < 1e-12) centre = v;
            if (std::abs(p.y()) < 1e-12 && p.x() > 0.019) on_x = v;
            fem.Hold(v, 2, 0.0);
          }
          ASSERT_GE(centre, 0);
          ASSERT_GE(on_x, 0);
          fem.Hold(centre, 0, 0.0);
          fem.Hold(centre, 1, 0.0);
          fem.Hold(on_x, 1, 0.0);
          for (int v : bar.tip) fem.Hold(v, 2, l1 * bar.params.length);
          const HyperelasticSolve s = fem.SolveStatic(60, 1e-10);
          ASSERT_TRUE(s.converged) << s.iterations << " iterations, residual " << s.residual;
          const auto [l2, stress] = UniaxialClosedForm(fem.mu(), fem.lambda(), b, l1);
          const Vec3 tip_edge = fem.positions()[on_x];
          EXPECT_NEAR(tip_edge.x() / bar.mesh.positions[on_x].x(), l2, 1e-8);
          const Eigen::VectorXd f = fem.InternalForces();
          double reaction = 0, area = 0;
          for (size_t i = 0; i < bar.tip.size(); ++i) {
            reaction -= f[3 * bar.tip[i] + 2];
            area += bar.tip_area[i];
          }
          EXPECT_NEAR(reaction / area, stress, 1e-7 * std::abs(stress));
          EXPECT_LE(s.iterations, 8);  // Newton with the exact tangent: 3–5 here
        }
      }
}

// The bar on rollers as above, its end held at `l1` (m/m) or loaded by `load` (N) spread by area.
struct HeldBar {
  geometry::TetCylinder bar = NeoHookeanBar();
  HyperelasticFem fem;
  explicit HeldBar(HyperelasticParams p) : fem(HyperelasticFem::Create(bar.mesh, p).value()) {
    int centre = -1, on_x = -1;
    for (int v : bar.base) {
      const Vec3& x = bar.mesh.positions[v];
      if (x.head<2>().norm() < 1e-12) centre = v;
      if (std::abs(x.y()) < 1e-12 && x.x() > 0.019) on_x = v;
      fem.Hold(v, 2, 0.0);
    }
    fem.Hold(centre, 0, 0.0);
    fem.Hold(centre, 1, 0.0);
    fem.Hold(on_x, 1, 0.0);
  }
  double Area() const { return std::accumulate(bar.tip_area.begin(), bar.tip_area.end(), 0.0); }
  void Stretch(double l1) {
    for (int v : bar.tip) fem.Hold(v, 2, l1 * bar.params.length);
  }
  void Load(double force) {
    for (size_t i = 0; i < bar.tip.size(); ++i)
      fem.SetExternalForce(bar.tip[i], Vec3(0, 0, force * bar.tip_area[i] / Area()));
  }
  double Reaction() const {  // N, along the axis, on the end
    const Eigen::VectorXd f = fem.InternalForces();
    double r = 0;
    for (int v : bar.tip) r -= f[3 * v + 2];
    return r;
  }
  double EndStretch() const {  // the end's mean axial stretch
    double z = 0;
    for (int v : bar.tip) z += fem.positions()[v].z();
    return z / static_cast<double>(bar.tip.size()) / bar.params.length;
  }
};

// Relaxation (quasi-linear viscoelasticity, one Prony term): a stretch applied in a step much
// shorter than τ and held; the end's force follows the elastic force times
// G(t) = g∞ + g·e^{−t/τ} (the uniform scaling leaves the lateral stretch as it is), at a large
// stretch (1.3) where the elastic force is itself nonlinear.
TEST(HyperelasticTest, AHeldStretchRelaxesAsThePronySeriesSays) {
  HeldBar b({30e3, 0.45, 2.0});
  const double g = 0.6, tau = 2.0;  // s
  ASSERT_TRUE(b.fem.SetRelaxation({{g, tau}}).ok());
  const double l1 = 1.3;
  std::vector<Vec3> guess = b.bar.mesh.positions;
  for (Vec3& p : guess) p.z() *= l1;
  b.fem.SetPositions(guess);
  b.Stretch(l1);
  const double step = 1e-4 * tau;
  ASSERT_TRUE(b.fem.Step(step).converged);
  const auto [l2, nominal] = UniaxialClosedForm(b.fem.mu(), b.fem.lambda(), 2.0, l1);
  const double elastic = nominal * b.Area();
  EXPECT_NEAR(b.Reaction() / elastic, 1.0, 1e-3) << "the instantaneous response is elastic";
  for (int k = 1; k <= 60; ++k) {
    ASSERT_TRUE(b.fem.Step(0.05 * tau).converged);
    if (k % 20 != 0) continue;
    const double t = b.fem.time() - step / 2;
    const double relax = (1 - g) + g * std::exp(-t / tau);
    EXPECT_NEAR(b.Reaction() / elastic, relax, 1e-3 * relax) << "t " << t << " s";
  }
}

// Creep of a standard linear solid: a small load (the linear range) applied in a step and held;
// the bar's strain follows ε(t) = σ/E∞ − (σ/E∞ − σ/E0)·e^{−t/τ_c}, E0 = E, E∞ = g∞·E and
// τ_c = τ·E0/E∞, within the step's error (τ/100 steps).
TEST(HyperelasticTest, AHeldLoadCreepsAsAStandardLinearSolid) {
  const double young = 30e3, g = 0.5, tau = 1.0;
  HeldBar b({young, 0.3, 0});
  ASSERT_TRUE(b.fem.SetRelaxation({{g, tau}}).ok());
  const double sigma = 1e-4 * young;  // Pa: a strain of 1e-4 at first
  b.Load(sigma * b.Area());
  const double e0 = young, e_inf = (1 - g) * young, tau_c = tau * e0 / e_inf;
  ASSERT_TRUE(b.fem.Step(1e-5).converged);
  EXPECT_NEAR((b.EndStretch() - 1) / (sigma / e0), 1.0, 2e-3);
  for (int k = 1; k <= 500; ++k) {
    ASSERT_TRUE(b.fem.Step(0.01 * tau).converged);
    if (k % 100 != 0) continue;
    const double t = b.fem.time();
    const double want = sigma / e_inf - (sigma / e_inf - sigma / e0) * std::exp(-t / tau_c);
    EXPECT_NEAR((b.EndStretch() - 1) / want, 1.0, 5e-3) << "t " << t << " s";
  }
  EXPECT_EQ(b.fem.SetRelaxation({{1.0, 1.0}}).error().field, "relaxation");
  EXPECT_EQ(b.fem.SetRelaxation({{0.2, 0.0}}).error().field, "relaxation[0]");
  EXPECT_EQ(b.fem.SetRelaxation({{0.2, 1.0}, {-0.1, 1.0}}).error().field, "relaxation[1]");
}

TEST(HyperelasticTest, BadMaterialsAndElementsAreRefusedByName) {
  const auto bar = NeoHookeanBar();
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {0, 0.3}).error().field, "young");
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {NAN, 0.3}).error().field, "young");
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {1e4, 0.5}).error().field, "poisson");
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {1e4, -1}).error().field, "poisson");
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {1e4, 0.3, -1}).error().field, "stiffening");
  EXPECT_EQ(HyperelasticFem::Create(bar.mesh, {1e4, 0.3, INFINITY}).error().field, "stiffening");
  geometry::TetMesh flipped = bar.mesh;
  std::swap(flipped.tetrahedra[3][0], flipped.tetrahedra[3][1]);
  EXPECT_EQ(HyperelasticFem::Create(flipped, {1e4, 0.3}).error().field.rfind("tetrahedra", 0), 0u);
  // The relaxation's history is per element: not with the volume at the vertices.
  auto nodal = HyperelasticFem::Create(bar.mesh, {1e4, 0.3, 0, true}).value();
  EXPECT_EQ(nodal.SetRelaxation({{0.3, 1.0}}).error().field, "relaxation");
  EXPECT_TRUE(nodal.SetRelaxation({}).ok());
}

// One tetrahedron, its apex pushed down through its base and beyond (J from 1 through 0 to −0.5):
// the energy stays finite and falls as the apex rises, the apex is always pushed up, the forces
// and the tangent stay the energy's exact derivatives in the inverted state, and a solve from it
// (the base held) brings the apex back to rest; for both volume forms, ν up to 0.499. The bar
// turned inside out (every element inverted) has a finite energy too.
TEST(HyperelasticTest, AnElementPushedInsideOutIsPushedBackAndTheSolveUntanglesIt) {
  const double h = 0.01;  // m
  geometry::TetMesh tet;
  tet.positions = {Vec3(0, 0, 0), Vec3(h, 0, 0), Vec3(0, h, 0), Vec3(0.2 * h, 0.2 * h, h)};
  tet.tetrahedra = {{0, 1, 2, 3}};
  for (const auto& [nu, nodal] : {std::pair{0.3, false}, {0.499, false}, {0.45, true}}) {
    SCOPED_TRACE("nu " + std::to_string(nu) + (nodal ? ", the volume at the vertices" : ""));
    auto fem = HyperelasticFem::Create(tet, {30e3, nu, 0, nodal}).value();
    std::vector<Vec3> x = tet.positions;
    double last_energy = -1;
    for (double z : {0.5, 0.1, 0.0, -0.2, -0.5}) {  // the apex's height, h
      x[3].z() = z * h;
      fem.SetPositions(x);
      const double e = fem.StrainEnergy();
      ASSERT_TRUE(std::isfinite(e)) << z;
      EXPECT_GT(e, last_energy) << z << ": deeper in, more energy";
      last_energy = e;
      EXPECT_GT(fem.InternalForces()[11], 0) << z << ": the apex pushed up";
    }
    // Exact derivatives in the inverted state (J = −0.3, the apex off its line).
    x[3] = Vec3(0.25 * h, 0.15 * h, -0.3 * h);
    ExpectExactDerivatives(fem, x, {0, 4, 9, 10, 11}, 1e-8);
    // From the inverted state back to rest, the base held.
    fem.SetPositions(x);
    for (int v = 0; v < 3; ++v)
      for (int c = 0; c < 3; ++c) fem.Hold(v, c, tet.positions[v][c]);
    const HyperelasticSolve solve = fem.SolveStatic(100, 1e-10);
    ASSERT_TRUE(solve.converged) << solve.residual;
    EXPECT_LT((fem.positions()[3] - tet.positions[3]).norm(), 1e-9);
    std::printf("nu %.3f%s: inverted apex back at rest in %d Newton steps\n", nu,
                nodal ? " (at the vertices)" : "", solve.iterations);
  }
  const auto bar = NeoHookeanBar();
  for (bool nodal : {false, true}) {
    auto fem = HyperelasticFem::Create(bar.mesh, {1e4, 0.3, 0, nodal}).value();
    std::vector<Vec3> x = bar.mesh.positions;
    for (Vec3& p : x) p.z() = -p.z();
    fem.SetPositions(x);
    EXPECT_TRUE(std::isfinite(fem.StrainEnergy())) << nodal;
    EXPECT_GT(fem.StrainEnergy(), 0) << nodal;
    EXPECT_TRUE(fem.InternalForces().allFinite()) << nodal;
  }
}

// The bar's end under a load applied at once and held (a step load), with inertia (implicit
// Euler): the end overshoots the static answer (an undamped bar would reach twice it, the scheme's
// dissipation less), every step the total energy (kinetic + strain − the load's work) falls, the
// ringing's period is the bar's first axial mode 4L/c (c = √(E/ρ), within the rod theory's and the
// mesh's error), and it settles on the static solve's answer. Implicit Euler is first order: the
// end's position at the first peak converges as h.
TEST(HyperelasticTest, AStepLoadRingsDownToTheStaticAnswerAndNeverGainsEnergy) {
  constexpr double kYoung = 30e3, kDensity = 1050, kStrain = 1e-3;
  const double period = 4 * 0.1 / std::sqrt(kYoung / kDensity);  // s, the rod's first mode
  const auto run = [&](double h, double until, std::vector<double>* ends, double* worst_rise) {
    HeldBar b({kYoung, 0.3, 0});
    EXPECT_TRUE(b.fem.SetDensity(kDensity).ok());
    b.Load(kStrain * kYoung * b.Area());
    double total = 0;
    for (double t = 0; t < until - 1e-12; t += h) {
      const HyperelasticSolve s = b.fem.Step(h);
      EXPECT_TRUE(s.converged) << t;
      const double now = b.fem.KineticEnergy() + b.fem.StrainEnergy() + b.fem.LoadPotential();
      if (worst_rise && t > 0) *worst_rise = std::max(*worst_rise, (now - total) / std::abs(total));
      total = now;
      if (ends) ends->push_back(b.EndStretch() - 1);
    }
    return b.EndStretch() - 1;
  };
  const double h = period / 80;
  std::vector<double> ends;
  double rise = -1;
  run(h, 6 * period, &ends, &rise);
  EXPECT_LT(rise, 1e-9) << "a step gained energy";
  // The static answer (the same load without inertia).
  HeldBar still({kYoung, 0.3, 0});
  still.Load(kStrain * kYoung * still.Area());
  ASSERT_TRUE(still.fem.SolveStatic().converged);
  const double static_end = still.EndStretch() - 1;
  const auto peak = std::max_element(ends.begin(), ends.end());
  std::vector<size_t> maxima;
  for (size_t k = 1; k + 1 < ends.size(); ++k)
    if (ends[k] > ends[k - 1] && ends[k] >= ends[k + 1] && ends[k] > static_end)
      maxima.push_back(k);
  ASSERT_GE(maxima.size(), 2u);
  const double ringing = static_cast<double>(maxima[1] - maxima[0]) * h;
  std::printf(
      "step load: peak %.3f× the static end, period %.4f s (rod %.4f s), end after 6 "
      "periods %.4f×, worst energy rise %.2e\n",
      *peak / static_end, ringing, period, ends.back() / static_end, rise);
  EXPECT_GT(*peak, 1.5 * static_end);
  EXPECT_LT(*peak, 2.0 * static_end);
  EXPECT_NEAR(ringing / period, 1.0, 0.1);
  // Settled: far longer steps (implicit Euler is stable at any) reach the static answer.
  HeldBar settle({kYoung, 0.3, 0});
  ASSERT_TRUE(settle.fem.SetDensity(kDensity).ok());
  settle.Load(kStrain * kYoung * settle.Area());
  for (int k = 0; k < 40; ++k) ASSERT_TRUE(settle.fem.Step(period).converged);
  EXPECT_NEAR((settle.EndStretch() - 1) / static_end, 1.0, 1e-6);
  // First order: the end at the first peak's time with h, h/2, h/4 against h/32.
  const double at = static_cast<double>(maxima[0] + 1) * h;
  const double fine = run(h / 32, at, nullptr, nullptr);
  double last_error = 0;
  for (const double step : {h, h / 2, h / 4}) {
    const double error = std::abs(run(step, at, nullptr, nullptr) - fine);
    if (last_error > 0) {
      const double order = std::log2(last_error / error);
      std::printf("h/%.0f: order %.2f\n", h / step, order);
      EXPECT_NEAR(order, 1.0, 0.25);
    }
    last_error = error;
  }
  EXPECT_EQ(settle.fem.SetDensity(-1).error().field, "density");
}

// The hard cases with inertia, on the coarsest mesh: dead step loads of 0.3 E pulling the
// exponential law's bar and 0.6 E pushing it, first in steps of 2 ms (a fortieth of the ringing),
// then of 50 ms. The push drives the end through the base: every element inverts, and the
// continued volumetric energy carries the bar inside out to rest there. Every step converges,
// stays bounded and finite, and the bar comes to rest where the static solve agrees.
TEST(HyperelasticTest, ALargeStepLoadWithInertiaStaysBoundedAndFinite) {
  for (const double load : {0.3, -0.6}) {  // the nominal stress over E
    SCOPED_TRACE("load " + std::to_string(load) + " E");
    HeldBar b({30e3, 0.45, 2.0});
    ASSERT_TRUE(b.fem.SetDensity(1050).ok());
    b.Load(load * 30e3 * b.Area());
    double lowest = 1e9, highest = -1e9;
    for (int k = 0; k < 60; ++k) {
      ASSERT_TRUE(b.fem.Step(k < 30 ? 2e-3 : 0.05).converged) << "step " << k;
      for (const Vec3& x : b.fem.positions()) ASSERT_TRUE(x.allFinite()) << "step " << k;
      lowest = std::min(lowest, b.EndStretch()), highest = std::max(highest, b.EndStretch());
    }
    std::printf("step load %+.1f E: end stretch %.3f..%.3f, at rest %.4f\n", load, lowest, highest,
                b.EndStretch());
    EXPECT_GT(lowest, load > 0 ? 1.0 : -1.0);
    EXPECT_LT(highest, load > 0 ? 1.5 : 1.0);
    EXPECT_LT(b.fem.KineticEnergy(), 1e-12 * b.fem.StrainEnergy());
    const double rest = b.EndStretch();
    ASSERT_TRUE(b.fem.SolveStatic().converged);
    EXPECT_NEAR(b.EndStretch(), rest, 1e-6);
  }
}

}  // namespace
}  // namespace vsurg::tissue
