#include "common/tissue/ring_layer.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/geometry/distances.h"
#include "common/geometry/mesh_generators.h"

namespace vsurg::tissue {
namespace {

using geometry::Vec3;

struct Fixture {
  geometry::TriMesh mesh;
  std::vector<double> rho, mass;
};

Fixture SphereWithDistances() {
  Fixture f;
  f.mesh =
      *geometry::MakeSubdividedSphere({0.05, 4, geometry::SphereBase::kOctahedron, Vec3::Zero()});
  auto sp = geometry::ClosestSurfacePoint(f.mesh, Vec3(0, 0, 1));
  f.rho = *geometry::GeodesicDistances(f.mesh, *sp, geometry::GeodesicMethod::kHeat);
  f.mass.assign(f.mesh.VertexCount(), 0.5 / f.mesh.VertexCount());
  return f;
}

RingLayerParams Params() {
  RingLayerParams p;
  p.ring_spacing = 0.008;
  p.rings = 6;
  p.chain_stiffness = 40;
  p.chain_damping = 0.05;
  return p;
}

TEST(RingLayerTest, StaticPressGivesALinearChainAndSeriesSpringForce) {
  Fixture f = SphereWithDistances();
  auto m = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), Params());
  ASSERT_TRUE(m.ok()) << m.error().message;
  m->SetContactDisplacement(0.004);
  m->SolveStatic();
  // K equal springs in series between the driven ring and the fixed one: u_k = d(1 − k/K).
  for (int k = 0; k <= 6; ++k) EXPECT_NEAR(m->displacements()[k], 0.004 * (1 - k / 6.0), 1e-15);
  EXPECT_NEAR(m->ContactForce(), 40.0 / 6 * 0.004, 1e-12);
  EXPECT_NEAR(m->PotentialEnergy(), 0.5 * 40.0 / 6 * 0.004 * 0.004, 1e-15);
}

TEST(RingLayerTest, ForceDriveAndTethersMatchTheStaticSolution) {
  Fixture f = SphereWithDistances();
  RingLayerParams p = Params();
  p.tether_stiffness = 2.0;
  auto m = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), p);
  ASSERT_TRUE(m.ok());
  m->SetContactForce(0.1);
  m->SolveStatic();
  const std::vector<double> u_static = m->displacements();
  EXPECT_GT(u_static[0], 0);
  // Tethers make the profile decay faster than linear.
  EXPECT_LT(u_static[3] / u_static[0], 0.5);
  // Dynamics with damping settle onto the same equilibrium; implicit Euler at a huge step too.
  for (double dt : {1e-3, 10.0}) {
    auto d = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), p);
    d->SetContactForce(0.1);
    for (int i = 0; i < 20000; ++i) ASSERT_TRUE(d->Step(dt));
    for (int k = 0; k <= p.rings; ++k) EXPECT_NEAR(d->displacements()[k], u_static[k], 1e-9) << dt;
    EXPECT_LT(d->KineticEnergy(), 1e-15);
  }
}

TEST(RingLayerTest, ApplyMovesOnlyVerticesInsideTheRingsAlongThePress) {
  Fixture f = SphereWithDistances();
  auto m = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), Params());
  m->SetContactDisplacement(0.004);
  m->SolveStatic();
  const int written = m->Apply();
  int inside = 0;
  for (int v = 0; v < f.mesh.VertexCount(); ++v) {
    const Vec3 d = m->positions()[v] - f.mesh.positions[v];
    EXPECT_NEAR(d.x(), 0, 1e-18);
    EXPECT_NEAR(d.y(), 0, 1e-18);
    EXPECT_LE(d.z(), 0);
    if (f.rho[v] >= 6 * 0.008) {
      EXPECT_EQ(d.norm(), 0.0);
    } else {
      ++inside;
      EXPECT_NEAR(-d.z(), 0.004 * (1 - f.rho[v] / (6 * 0.008)), 1e-12);  // linear in ρ
    }
  }
  EXPECT_EQ(written, inside);
}

TEST(RingLayerTest, EmptyRingsAndBadParametersAreRejected) {
  Fixture f = SphereWithDistances();
  RingLayerParams p = Params();
  p.ring_spacing = 0.0005;  // finer than the mesh: ring 1 is empty
  auto m = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), p);
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().field, "ring_spacing");
  p = Params();
  p.chain_stiffness = 0;
  EXPECT_EQ(
      RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), p).error().field,
      "chain_stiffness");
  EXPECT_EQ(
      RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3::Zero(), Params()).error().field,
      "press_direction");
  f.mass[3] = -1;
  EXPECT_EQ(RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), Params())
                .error()
                .field,
            "masses");
}

TEST(RingLayerTest, NonFiniteDrivesAreIgnored) {
  Fixture f = SphereWithDistances();
  auto m = RingLayerModel::Create(f.mesh.positions, f.rho, f.mass, Vec3(0, 0, -1), Params());
  m->SetContactDisplacement(0.002);
  m->SetContactDisplacement(NAN);
  m->SetContactForce(INFINITY);
  EXPECT_FALSE(m->Step(NAN));
  ASSERT_TRUE(m->Step(1e-3));
  for (double u : m->displacements()) EXPECT_TRUE(std::isfinite(u));
  EXPECT_NEAR(m->displacements()[0], 0.002, 1e-15);
}

}  // namespace
}  // namespace vsurg::tissue
