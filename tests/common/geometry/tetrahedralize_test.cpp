#include "common/geometry/tetrahedralize.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::geometry::tetrahedralize_test {
namespace {

TEST(TetrahedralizeTest, ABallHasTheVolumeOfTheSurfaceItCameFrom) {
  // A 5 cm sphere of 1,026 vertices: the tetrahedra fill the polyhedron the surface is (its own
  // volume, to the facet distance), which is within 1.5% of the analytic ball.
  auto sphere = MakeSubdividedSphere({0.05, 4, SphereBase::kOctahedron});
  ASSERT_TRUE(sphere.ok());
  TetQuality q;
  auto tets = Tetrahedralize(*sphere,
                             {.size = 0.006, .facet_distance = 0.0004, .radius_edge_ratio = 3}, &q);
  ASSERT_TRUE(tets.ok()) << tets.error().message;
  EXPECT_TRUE(Validate(*tets, 1e-15).ok());
  EXPECT_EQ(q.tets, tets->TetCount());
  EXPECT_GT(q.tets, 300);
  const double ball = 4.0 / 3.0 * std::numbers::pi * std::pow(0.05, 3);
  EXPECT_NEAR(q.volume, SignedVolume(*sphere), 0.02 * ball);
  EXPECT_NEAR(q.volume, ball, 0.03 * ball);
  EXPECT_GT(q.min_dihedral_deg, 2.0);  // no slivers left flat enough to break a FEM
  EXPECT_LT(q.max_dihedral_deg, 178.0);
  // Every vertex inside or on the ball (to the facet distance).
  for (const Vec3& p : tets->positions) EXPECT_LT(p.norm(), 0.05 + 1e-3);
  // The same on every run (no random perturbation).
  auto again =
      Tetrahedralize(*sphere, {.size = 0.006, .facet_distance = 0.0004, .radius_edge_ratio = 3});
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->TetCount(), tets->TetCount());
  EXPECT_EQ(again->positions, tets->positions);
}

TEST(TetrahedralizeTest, OpenOrSelfIntersectingSurfacesAreRefusedSayingWhere) {
  auto sphere = MakeSubdividedSphere({0.05, 2, SphereBase::kOctahedron});
  ASSERT_TRUE(sphere.ok());
  TriMesh open = *sphere;
  open.triangles.pop_back();
  auto e = Tetrahedralize(open);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("not closed"), std::string::npos) << e.error().message;
  EXPECT_NE(e.error().message.find("vertices"), std::string::npos) << e.error().message;
  // Two overlapping balls in one mesh: closed, but the surfaces cross.
  TriMesh two = *sphere;
  const int n = two.VertexCount();
  for (int i = 0; i < n; ++i) two.positions.push_back(sphere->positions[i] + Vec3(0.03, 0, 0));
  for (const Triangle& t : sphere->triangles)
    two.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});
  e = Tetrahedralize(two);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("intersects itself"), std::string::npos) << e.error().message;
  // Flipped triangle: not consistently oriented.
  TriMesh flipped = *sphere;
  std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
  e = Tetrahedralize(flipped);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("oriented"), std::string::npos) << e.error().message;
}

}  // namespace
}  // namespace vsurg::geometry::tetrahedralize_test
