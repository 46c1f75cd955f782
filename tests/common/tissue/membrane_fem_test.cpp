// MembraneFem (common/tissue/membrane_fem.h): the flat patch under its frame's pre-strain is in
// equilibrium at the stated tension; its forces are its energy's gradient; a small pressure meets
// the membrane equation's series solution to second order in the edge; a cut patch lifted by a
// grasper opens along the cut and converges; bad input is refused by name.
#include "common/tissue/membrane_fem.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "common/tissue/cut_membrane.h"

namespace vsurg::tissue {
namespace {

using geometry::Vec3;

CutMembrane FramedPatch(int cells) {
  CutMembraneParams p;
  p.cells = cells;
  auto m = CutMembrane::Create(p);
  EXPECT_TRUE(m.ok()) << m.error().message;
  return std::move(*m);
}

MembraneFem FemOf(const CutMembrane& patch, MembraneFemParams p = {}) {
  auto fem = MembraneFem::Create(MeshOf(patch), p);
  EXPECT_TRUE(fem.ok()) << fem.error().message;
  return std::move(*fem);
}

double Largest(const std::vector<Vec3>& f) {
  double m = 0;
  for (const Vec3& v : f) m = std::max(m, v.norm());
  return m;
}

TEST(MembraneFemTest, AFlatPatchUnderItsFramesPreStrainIsInEquilibriumAtTheStatedTension) {
  const CutMembrane patch = FramedPatch(16);
  const MembraneFem fem = FemOf(patch);
  // The tension pulls on every edge by about T·h; what is left at rest is rounding.
  const double t = fem.Tension();
  EXPECT_LT(Largest(fem.Forces()), 1e-9 * t * patch.EdgeLength());
  // Small strain: a biaxial pre-strain ε under plane stress is a tension E·t·ε / (1 − ν).
  const MembraneFemParams p;
  const double linear = p.youngs_modulus * p.thickness * p.pretension / (1 - p.poisson_ratio);
  EXPECT_NEAR(t, linear, 0.04 * linear);  // Green's strain at 2% is 3% above the linear one
}

TEST(MembraneFemTest, ItsForcesAreMinusTheGradientOfItsEnergy) {
  const CutMembrane patch = FramedPatch(8);
  MembraneFem fem = FemOf(patch);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  std::vector<Vec3> x = fem.positions();
  for (Vec3& v : x) v += Vec3(jitter(rng), jitter(rng), 3 * jitter(rng));
  fem.SetPositions(x);
  fem.SetLoad(20, Vec3(0.1, -0.2, 0.3));
  fem.Hold(30, Vec3(0.001, 0.002, 0.004), 500);
  const std::vector<Vec3> f = fem.Forces();
  const double h = 1e-7;
  int checked = 0;
  for (int i = 0; i < fem.VertexCount(); i += 7) {
    if (f[i].isZero()) continue;  // held by the frame
    for (int c = 0; c < 3; ++c) {
      std::vector<Vec3> plus = x, minus = x;
      plus[i][c] += h, minus[i][c] -= h;
      fem.SetPositions(plus);
      const double wp = fem.Energy();
      fem.SetPositions(minus);
      const double wm = fem.Energy();
      EXPECT_NEAR(f[i][c], -(wp - wm) / (2 * h), 1e-6 * (1 + std::abs(f[i][c])))
          << "vertex " << i << " axis " << c;
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
}

// −T·∇²w = p on the frame's a × b rectangle (origin at its centre), w = 0 on its rim, for
// p = p0·sin(π(x + a/2)/a)·sin(π(y + b/2)/b): w = p / (T·π²·(1/a² + 1/b²)). (A uniform pressure
// would not do: the lattice's stencil is exact to fourth order for it.)
double Mode(double a, double b, const Eigen::Vector2d& at) {
  const double pi = std::numbers::pi;
  return std::sin(pi * (at.x() + 0.5 * a) / a) * std::sin(pi * (at.y() + 0.5 * b) / b);
}

// A pressure of 0.01 Pa at most (dead, on the frame's area, lumped a third of each face to its
// corners) lifts the patch 0.1 µm: its own stretch is negligible against the pre-strain's 2%, so
// the answer is the linear membrane's. Returns the largest difference from w at a vertex, over
// w's largest value.
double ErrorUnderPressure(int cells) {
  constexpr double kP0 = 0.01;  // Pa
  const CutMembrane patch = FramedPatch(cells);
  const MembraneMesh mesh = MeshOf(patch);
  MembraneFem fem = FemOf(patch);
  const double a = patch.params().size_x, b = patch.params().size_y;
  std::vector<Vec3> load(mesh.rest.size(), Vec3::Zero());
  for (const auto& f : mesh.faces) {
    const Eigen::Vector2d u = mesh.rest[f[1]] - mesh.rest[f[0]];
    const Eigen::Vector2d v = mesh.rest[f[2]] - mesh.rest[f[0]];
    const double area = 0.5 * (u.x() * v.y() - u.y() * v.x());
    for (int32_t k : f) load[k] += Vec3(0, 0, kP0 * Mode(a, b, mesh.rest[k]) * area / 3);
  }
  for (size_t i = 0; i < load.size(); ++i) fem.SetLoad(static_cast<int>(i), load[i]);
  auto solved = fem.SolveStatic(1e-13);
  EXPECT_TRUE(solved.ok() && solved->converged);
  if (solved.ok()) {
    EXPECT_LE(solved->iterations, 4);  // Newton on an exact tangent
  }
  const double pi = std::numbers::pi;
  const double peak = kP0 / (fem.Tension() * pi * pi * (1 / (a * a) + 1 / (b * b)));
  double worst = 0;
  for (size_t i = 0; i < mesh.rest.size(); ++i)
    worst = std::max(worst, std::abs(fem.positions()[i].z() - peak * Mode(a, b, mesh.rest[i])));
  EXPECT_GT(peak, 5e-8);
  return worst / peak;
}

// 8, 16, 32 cells: 1.87%, 0.48%, 0.12% (3.9× and 4.1× at each halving).
TEST(MembraneFemTest, ASmallPressureMeetsTheMembraneEquationToSecondOrder) {
  std::vector<double> errors;
  for (int cells : {8, 16, 32}) errors.push_back(ErrorUnderPressure(cells));
  EXPECT_LT(errors.back(), 0.01) << errors[0] << " " << errors[1] << " " << errors[2];
  EXPECT_GT(errors[0] / errors[1], 3.0);  // second order: 4 at each halving
  EXPECT_GT(errors[1] / errors[2], 3.0);
}

TEST(MembraneFemTest, ACutPatchLiftedByAGrasperOpensAlongTheCutAndConverges) {
  CutMembrane patch = FramedPatch(24);
  // Half of the drill's circle, 15 mm across the centre, on its right.
  const int steps = 60;
  for (int k = 0; k < steps; ++k) {
    const double a0 = -0.5 * std::numbers::pi + std::numbers::pi * k / steps;
    const double a1 = -0.5 * std::numbers::pi + std::numbers::pi * (k + 1) / steps;
    patch.Cut(0.015 * Vec2(std::cos(a0), std::sin(a0)), 0.015 * Vec2(std::cos(a1), std::sin(a1)));
  }
  ASSERT_GT(patch.cut_edges().size(), 10u);
  MembraneFem fem = FemOf(patch);
  int flap = 0;  // the particle nearest 8 mm right of the centre, inside the cut
  for (int i = 0; i < fem.VertexCount(); ++i)
    if ((patch.Rest(i) - Vec2(0.008, 0)).norm() < (patch.Rest(flap) - Vec2(0.008, 0)).norm())
      flap = i;
  fem.Hold(flap, Vec3(0.008, 0, 0.006), 2000);
  auto solved = fem.SolveStatic(1e-8, 200);
  ASSERT_TRUE(solved.ok()) << solved.error().message;
  EXPECT_TRUE(solved->converged) << solved->residual;
  // The two sides of every cut node part: the flap's side rises above the rim's.
  double widest = 0;
  for (int i = 0; i < fem.VertexCount(); ++i) {
    const Vec3& x = fem.positions()[i];
    ASSERT_TRUE(x.allFinite());
    for (int j = i + 1; j < fem.VertexCount(); ++j)
      if (patch.NodeOf(j) == patch.NodeOf(i))
        widest = std::max(widest, (fem.positions()[j] - x).norm());
  }
  EXPECT_GT(widest, 1e-3);
  EXPECT_GT(fem.positions()[flap].z(), 0.004);
}

TEST(MembraneFemTest, BadParametersAndMeshesAreRefusedByName) {
  const CutMembrane patch = FramedPatch(8);
  const MembraneMesh mesh = MeshOf(patch);
  const auto refused = [&](MembraneFemParams p, const std::string& field) {
    auto fem = MembraneFem::Create(mesh, p);
    ASSERT_FALSE(fem.ok()) << field;
    EXPECT_EQ(fem.error().field, field);
  };
  refused({.thickness = 0}, "thickness");
  refused({.youngs_modulus = std::nan("")}, "youngs_modulus");
  refused({.poisson_ratio = 0.5}, "poisson_ratio");
  refused({.pretension = -0.1}, "pretension");
  MembraneMesh flipped = mesh;
  std::swap(flipped.faces[3][1], flipped.faces[3][2]);
  auto fem = MembraneFem::Create(flipped, {});
  ASSERT_FALSE(fem.ok());
  EXPECT_EQ(fem.error().field, "faces");
  MembraneMesh outside = mesh;
  outside.faces[0][0] = static_cast<int32_t>(mesh.rest.size());
  fem = MembraneFem::Create(outside, {});
  ASSERT_FALSE(fem.ok());
  EXPECT_EQ(fem.error().field, "faces");
}

}  // namespace
}  // namespace vsurg::tissue
