#include "common/tissue/coil_deformation.h"

#include <cmath>
#include <memory>
#include <numbers>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::tissue {
namespace {

using geometry::Vec3;

// A forearm-sized limb with a coarse coil model whose rings are not aligned with the mesh rings.
struct LimbFixture {
  geometry::Limb limb;
  CoilSpringModel model;
  CoilDeformer deformer;
};

LimbFixture MakeLimbFixture() {
  geometry::LimbParams lp = geometry::ForearmPreset();
  lp.segments_around = 24;
  lp.rings_along = 51;
  auto limb = geometry::MakeLimb(lp);
  CoilSpringParams cp;
  cp.core_radius = 0.013;
  cp.thickness = 0.0117;
  cp.coils = 20;
  cp.width = 0.06;
  cp.modulus = 4e8;
  cp.max_force = 0.2;
  auto model = CoilSpringModel::Create(cp);
  auto def =
      CoilDeformer::CreateForLimb(*model, limb->surface.positions, limb->centreline, lp.length);
  EXPECT_TRUE(def.ok()) << def.error().message;
  return {*limb, *model, *def};
}

// Distance from p to the limb axis (the z axis) and its angle about it.
double AxisDistance(const Vec3& p) {
  return std::hypot(p.x(), p.y());
}
double AxisAngle(const Vec3& p) {
  return std::atan2(p.y(), p.x());
}
double WrapPi(double a) {
  return std::remainder(a, 2 * std::numbers::pi);
}

TEST(CoilDeformationTest, LimbVerticesTurnByTheTwistAtTheirDistanceAndKeepTheirRadius) {
  LimbFixture f = MakeLimbFixture();
  const double length = f.limb.params.length;
  for (double torque : {0.3, 1.7, -2.2}) {
    const DeformStats stats = f.deformer.Update(torque);
    ASSERT_GT(stats.cutoff, 0);
    const CoilState& st = f.deformer.state();
    for (int v = 0; v < f.limb.surface.VertexCount(); ++v) {
      const Vec3& x0 = f.limb.surface.positions[v];
      const Vec3& x = f.deformer.positions()[v];
      EXPECT_NEAR(AxisDistance(x), AxisDistance(x0), 1e-15);
      EXPECT_NEAR(x.z(), x0.z(), 1e-15);  // a pure twist: nothing moves along the axis
      if (AxisDistance(x0) > 1e-6) {
        const double expected = f.model.TwistAt(length - x0.z(), st);
        EXPECT_NEAR(WrapPi(AxisAngle(x) - AxisAngle(x0) - expected), 0, 1e-12) << v;
      }
    }
  }
}

TEST(CoilDeformationTest, OnlyVerticesInsideTheCutoffRadiusMove) {
  LimbFixture f = MakeLimbFixture();
  const double length = f.limb.params.length;
  const DeformStats stats = f.deformer.Update(1.0);
  const double cutoff_radius = f.model.RingRadius(stats.cutoff);
  ASSERT_LT(cutoff_radius, length);  // the test needs a partial cutoff
  int moved = 0;
  for (int v = 0; v < f.limb.surface.VertexCount(); ++v) {
    const double rho = length - f.limb.surface.positions[v].z();
    const bool changed = f.deformer.positions()[v] != f.limb.surface.positions[v];
    if (rho >= cutoff_radius) {
      EXPECT_FALSE(changed) << "vertex " << v << " at rho " << rho;
    }
    if (changed) ++moved;
  }
  EXPECT_GT(moved, 0);
  // Every vertex strictly inside R_P is counted (the proximal cap centre lies on the axis).
  int inside = 0;
  for (const Vec3& p : f.limb.surface.positions) inside += (length - p.z()) < cutoff_radius;
  EXPECT_EQ(stats.moved_vertices, inside);
}

TEST(CoilDeformationTest, SmallerTorqueAfterLargerPutsOuterVerticesBackAtRest) {
  LimbFixture f = MakeLimbFixture();
  const DeformStats big = f.deformer.Update(2.5);
  const DeformStats small = f.deformer.Update(0.2);
  ASSERT_LT(small.cutoff, big.cutoff);
  EXPECT_EQ(small.touched_vertices, big.moved_vertices);
  const double cutoff_radius = f.model.RingRadius(small.cutoff);
  for (int v = 0; v < f.limb.surface.VertexCount(); ++v) {
    if (f.limb.params.length - f.limb.surface.positions[v].z() >= cutoff_radius) {
      EXPECT_EQ(f.deformer.positions()[v], f.limb.surface.positions[v]);
    }
  }
  const DeformStats none = f.deformer.Update(0.0);
  EXPECT_EQ(none.moved_vertices, 0);
  EXPECT_EQ(f.deformer.positions(), f.limb.surface.positions);
}

TEST(CoilDeformationTest, RepeatedUpdatesDoNotDrift) {
  LimbFixture f = MakeLimbFixture();
  f.deformer.Update(1.3);
  const std::vector<Vec3> first = f.deformer.positions();
  for (int k = 0; k < 1000; ++k) f.deformer.Update(k % 2 ? -2.9 : 0.7);
  f.deformer.Update(1.3);
  EXPECT_EQ(f.deformer.positions(), first);  // always from rest: bit-identical
}

// The deferred path: Evaluate moves the model and no vertex, and the vertices a reader makes from
// the table and the state are the ones Update writes, to the bit, however the cutoff moves
// (growing, shrinking, through zero, overloaded) and on a copy of the table that outlives the
// deformer's next binding.
TEST(CoilDeformationTest, VerticesMadeFromTheTableAndStateAreTheUpdatesOwn) {
  LimbFixture f = MakeLimbFixture();
  LimbFixture eager = MakeLimbFixture();
  const std::shared_ptr<const CoilTurnTable> table = f.deformer.table();
  std::vector<Vec3> made;
  for (const double torque : {0.4, 2.5, 0.2, -1.7, 0.0, 50.0, -0.05}) {
    const DeformStats lazy = f.deformer.Evaluate(torque);
    const DeformStats full = eager.deformer.Update(torque);
    EXPECT_EQ(f.deformer.positions(), f.limb.surface.positions) << "Evaluate turned a vertex";
    EXPECT_EQ(lazy.cutoff, full.cutoff);
    EXPECT_EQ(lazy.moved_vertices, full.moved_vertices);
    EXPECT_EQ(lazy.overload, full.overload);
    EXPECT_EQ(lazy.touched_vertices, 0);
    CoilDeformer::TurnFromRest(*table, f.deformer.state(), made);
    EXPECT_EQ(made, eager.deformer.positions()) << "at " << torque << " N·m";
  }
  // Update after Evaluates puts back what it last wrote (nothing) and turns the state's groups.
  f.deformer.Update(1.1);
  eager.deformer.Update(1.1);
  EXPECT_EQ(f.deformer.positions(), eager.deformer.positions());
  f.deformer = *CoilDeformer::CreateForLimb(f.model, f.limb.surface.positions, f.limb.centreline,
                                            0.5 * f.limb.params.length);
  CoilDeformer::TurnFromRest(*table, eager.deformer.state(), made);
  EXPECT_EQ(made, eager.deformer.positions()) << "the old binding's table still makes its twist";
}

TEST(CoilDeformationTest, OverloadedTorqueDeformsAsTheCapacity) {
  LimbFixture f = MakeLimbFixture();
  f.deformer.Update(f.model.Capacity());
  const std::vector<Vec3> at_capacity = f.deformer.positions();
  const DeformStats over = f.deformer.Update(10 * f.model.Capacity());
  EXPECT_TRUE(over.overload);
  EXPECT_EQ(over.cutoff, f.model.coils());
  EXPECT_EQ(f.deformer.positions(), at_capacity);
}

TEST(CoilDeformationTest, SurfaceModeTurnsAboutTheGraspNormalWithinTheGeodesicCutoff) {
  auto sphere =
      geometry::MakeSubdividedSphere({0.05, 4, geometry::SphereBase::kOctahedron, Vec3::Zero()});
  ASSERT_TRUE(sphere.ok());
  auto grasp = geometry::ClosestSurfacePoint(*sphere, Vec3(0, 0, 1));
  ASSERT_TRUE(grasp.ok());
  CoilSpringParams cp;
  cp.core_radius = 0.004;
  cp.thickness = 0.004;
  cp.coils = 10;
  cp.width = 0.01;
  cp.modulus = 1e9;
  cp.max_force = 0.5;
  auto model = CoilSpringModel::Create(cp);
  ASSERT_TRUE(model.ok());
  auto def =
      CoilDeformer::CreateForSurface(*model, *sphere, *grasp, geometry::GeodesicMethod::kHeat);
  ASSERT_TRUE(def.ok()) << def.error().message;
  const DeformStats stats = def->Update(0.05);
  ASSERT_GT(stats.cutoff, 1);
  ASSERT_GT(stats.moved_vertices, 0);
  const Vec3 g = geometry::PositionOf(*sphere, *grasp);
  const Vec3 n = geometry::NormalOf(*sphere, *grasp);
  const double cutoff_radius = model->RingRadius(stats.cutoff);
  for (int v = 0; v < sphere->VertexCount(); ++v) {
    const Vec3 r0 = sphere->positions[v] - g, r1 = def->positions()[v] - g;
    // Distance to the axis and height along it are kept.
    EXPECT_NEAR((r1 - r1.dot(n) * n).norm(), (r0 - r0.dot(n) * n).norm(), 1e-15);
    EXPECT_NEAR(r1.dot(n), r0.dot(n), 1e-15);
    if (def->distances()[v] >= cutoff_radius) {
      EXPECT_EQ(def->positions()[v], sphere->positions[v]);
    }
  }
}

// A room binds each grasp from projections made once: the same deformer as projecting anew.
TEST(CoilDeformationTest, ABindingFromProjectionsMadeOnceIsTheSameDeformer) {
  LimbFixture f = MakeLimbFixture();
  const auto& rest = f.limb.surface.positions;
  const auto projection = geometry::ProjectOntoPolyline(rest, f.limb.centreline);
  ASSERT_TRUE(projection.ok());
  const double length = geometry::ArcLengths(f.limb.centreline).back();
  for (double arc : {0.0, 0.4 * length, length}) {
    auto once = CoilDeformer::CreateForLimb(f.model, rest, *projection, length, arc);
    auto anew = CoilDeformer::CreateForLimb(f.model, rest, f.limb.centreline, arc);
    ASSERT_TRUE(once.ok() && anew.ok());
    once->Update(1.3), anew->Update(1.3);
    EXPECT_EQ(once->positions(), anew->positions()) << arc;
    EXPECT_EQ(once->distances(), anew->distances()) << arc;
  }
  // The projections must be the mesh's, one per vertex.
  std::vector<geometry::CentrelineProjection> short_by_one(projection->begin(),
                                                           projection->end() - 1);
  const auto refused = CoilDeformer::CreateForLimb(f.model, rest, short_by_one, length, 0.1);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("one projection per vertex"), std::string::npos);
  EXPECT_FALSE(CoilDeformer::CreateForLimb(f.model, rest, *projection, length, length * 1.01).ok());
}

TEST(CoilDeformationTest, BadBindingsAreRejected) {
  LimbFixture f = MakeLimbFixture();
  EXPECT_FALSE(CoilDeformer::CreateForLimb(f.model, {}, f.limb.centreline, 0).ok());
  EXPECT_FALSE(
      CoilDeformer::CreateForLimb(f.model, f.limb.surface.positions, f.limb.centreline, -0.1).ok());
  EXPECT_FALSE(
      CoilDeformer::CreateForLimb(f.model, f.limb.surface.positions, f.limb.centreline, 1.0).ok());
  EXPECT_FALSE(
      CoilDeformer::CreateForLimb(f.model, f.limb.surface.positions, {Vec3::Zero()}, 0).ok());
}

}  // namespace
}  // namespace vsurg::tissue
