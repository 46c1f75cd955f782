#include "common/geometry/mesh_generators.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace vsurg::geometry {
namespace {

void ExpectClosedAndOutward(const TriMesh& m) {
  ASSERT_TRUE(Validate(m).ok());
  const TopologyReport r = CheckTopology(m);
  EXPECT_TRUE(r.Closed()) << r.boundary_edges << " boundary, " << r.non_manifold_edges
                          << " non-manifold";
  EXPECT_TRUE(r.ConsistentlyOriented()) << r.misoriented_edges << " misoriented edges";
  EXPECT_EQ(r.euler_characteristic, 2);  // a sphere-like surface
  EXPECT_GT(SignedVolume(m), 0);         // outward
}

TEST(SphereTest, OctahedronLevelsGiveThePaperParticleCounts) {
  // the mass-spring paper Fig. 2-2: spheres of about 256 and 1024 particles.
  EXPECT_EQ(SphereVertexCount(SphereBase::kOctahedron, 3), 258);
  EXPECT_EQ(SphereVertexCount(SphereBase::kOctahedron, 4), 1026);
  EXPECT_EQ(SphereLevelsForVertexCount(SphereBase::kOctahedron, 256), 3);
  EXPECT_EQ(SphereLevelsForVertexCount(SphereBase::kOctahedron, 1024), 4);
  EXPECT_EQ(SphereVertexCount(SphereBase::kIcosahedron, 2), 162);
  for (int levels : {3, 4}) {
    auto m = MakeSubdividedSphere({0.05, levels, SphereBase::kOctahedron, Vec3::Zero()});
    ASSERT_TRUE(m.ok());
    EXPECT_EQ(m->VertexCount(), SphereVertexCount(SphereBase::kOctahedron, levels));
    EXPECT_EQ(m->TriangleCount(), 8 << (2 * levels));
  }
}

TEST(SphereTest, SubdividedSpheresAreClosedOutwardAndOnTheSphere) {
  for (SphereBase base : {SphereBase::kOctahedron, SphereBase::kIcosahedron}) {
    for (int levels = 0; levels <= 4; ++levels) {
      SCOPED_TRACE(levels);
      const Vec3 c(0.1, -0.2, 0.3);
      auto m = MakeSubdividedSphere({0.05, levels, base, c});
      ASSERT_TRUE(m.ok());
      ExpectClosedAndOutward(*m);
      for (int v = 0; v < m->VertexCount(); ++v) {
        EXPECT_NEAR((m->positions[v] - c).norm(), 0.05, 1e-15);
        EXPECT_GT(m->normals[v].dot(m->positions[v] - c), 0);  // normals point out
      }
    }
  }
}

TEST(SphereTest, VolumeConvergesToTheBallFromBelowAtSecondOrder) {
  const double exact = 4.0 / 3.0 * std::numbers::pi * 0.125;  // R = 0.5
  double prev_err = 0;
  for (int levels = 2; levels <= 6; ++levels) {
    auto m = MakeSubdividedSphere({0.5, levels, SphereBase::kOctahedron, Vec3::Zero()});
    ASSERT_TRUE(m.ok());
    const double err = exact - SignedVolume(*m);
    EXPECT_GT(err, 0);  // an inscribed polyhedron
    if (levels > 2) {
      EXPECT_NEAR(prev_err / err, 4.0, 0.6);  // edge length halves: error / 4
    }
    prev_err = err;
  }
}

TEST(SphereTest, BadParametersAreRejected) {
  EXPECT_FALSE(MakeSubdividedSphere({0.0, 2, SphereBase::kOctahedron, Vec3::Zero()}).ok());
  EXPECT_FALSE(MakeSubdividedSphere({-1.0, 2, SphereBase::kOctahedron, Vec3::Zero()}).ok());
  EXPECT_FALSE(MakeSubdividedSphere({NAN, 2, SphereBase::kOctahedron, Vec3::Zero()}).ok());
  auto m = MakeSubdividedSphere({1.0, 9, SphereBase::kOctahedron, Vec3::Zero()});
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().field, "levels");
}

TEST(LimbTest, DefaultForearmHasThePaperArmSize) {
  // the coil-spring paper §3: 6185 particles and 12362 triangles.
  auto limb = MakeLimb(ForearmPreset());
  ASSERT_TRUE(limb.ok());
  EXPECT_NEAR(limb->surface.VertexCount(), 6185, 10);
  EXPECT_NEAR(limb->surface.TriangleCount(), 12362, 10);
  ExpectClosedAndOutward(limb->surface);
}

TEST(LimbTest, VolumeMatchesTheFrustumAndRadiusTapers) {
  for (const LimbParams& p : {ForearmPreset(), CalfPreset()}) {
    auto limb = MakeLimb(p);
    ASSERT_TRUE(limb.ok());
    ExpectClosedAndOutward(limb->surface);
    const double a0 = p.radius_proximal, a1 = p.radius_distal;
    const double frustum = std::numbers::pi * p.length / 3.0 * (a0 * a0 + a0 * a1 + a1 * a1);
    // An inscribed n-gon has area (n/2)·sin(2π/n)·a², slightly less than πa².
    const double polygon = p.segments_around / 2.0 *
                           std::sin(2 * std::numbers::pi / p.segments_around) / std::numbers::pi;
    EXPECT_NEAR(SignedVolume(limb->surface), frustum * polygon, 1e-9);
    EXPECT_DOUBLE_EQ(limb->RadiusAt(0), a0);
    EXPECT_DOUBLE_EQ(limb->RadiusAt(p.length), a1);
    ASSERT_EQ(static_cast<int>(limb->centreline.size()), p.rings_along);
    EXPECT_DOUBLE_EQ(limb->centreline.back().z(), p.length);
  }
}

TEST(LimbTest, ResolutionScalesTheVertexCount) {
  for (int target : {500, 2000, 20000}) {
    auto limb = MakeLimb(WithResolution(ForearmPreset(), target));
    ASSERT_TRUE(limb.ok());
    EXPECT_NEAR(limb->surface.VertexCount(), target, 0.1 * target);
    ExpectClosedAndOutward(limb->surface);
  }
}

TEST(LimbTest, BadParametersNameTheField) {
  LimbParams p = ForearmPreset();
  p.radius_distal = 0;
  auto limb = MakeLimb(p);
  ASSERT_FALSE(limb.ok());
  EXPECT_EQ(limb.error().field, "radius_distal");
  p = ForearmPreset();
  p.segments_around = 2;
  EXPECT_EQ(MakeLimb(p).error().field, "segments_around");
  p = ForearmPreset();
  p.length = INFINITY;
  EXPECT_EQ(MakeLimb(p).error().field, "length");
}

}  // namespace
}  // namespace vsurg::geometry
