#include "common/geometry/tet_generators.h"

#include <cmath>
#include <map>
#include <numbers>

#include <gtest/gtest.h>

namespace vsurg::geometry {
namespace {

double Volume(const TetMesh& m) {
  double v = 0;
  for (int t = 0; t < m.TetCount(); ++t) v += TetVolume(m, t);
  return v;
}

// Every face of the mesh is shared by one (boundary) or two (interior) tetrahedra, never more:
// the split is conforming (two prisms cut their shared face the same way).
void ExpectConforming(const TetMesh& m) {
  std::map<std::array<int, 3>, int> faces;
  for (const auto& t : m.tetrahedra)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f;
      int k = 0;
      for (int i = 0; i < 4; ++i)
        if (i != skip) f[k++] = t[i];
      std::sort(f.begin(), f.end());
      ++faces[f];
    }
  for (const auto& [f, n] : faces) ASSERT_LE(n, 2);
}

TEST(TetGeneratorsTest, CylinderIsPositiveConformingAndHasTheFrustumVolume) {
  for (int rings : {1, 2, 4, 8}) {
    auto c = MakeTetCylinder({0.25, 0.04, 0.03, rings, 10});
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_TRUE(Validate(c->mesh, 0.0).ok());
    ExpectConforming(c->mesh);
    // An inscribed polygon of 6·rings sides: area factor (n/2)·sin(2π/n)/π.
    const int n = 6 * rings;
    const double factor = n / 2.0 * std::sin(2 * std::numbers::pi / n) / std::numbers::pi;
    const double frustum = std::numbers::pi * 0.25 * (0.04 * 0.04 + 0.04 * 0.03 + 0.03 * 0.03) / 3;
    EXPECT_NEAR(Volume(c->mesh) / frustum, factor, 1e-9) << rings;
    EXPECT_EQ(c->mesh.TetCount(), 3 * 6 * rings * rings * 10);
    double area = 0;
    for (double a : c->tip_area) area += a;
    EXPECT_NEAR(area, factor * std::numbers::pi * 0.03 * 0.03, 1e-12);
    for (int v : c->tip) EXPECT_DOUBLE_EQ(c->mesh.positions[v].z(), 0.25);
    for (int v : c->base) EXPECT_DOUBLE_EQ(c->mesh.positions[v].z(), 0.0);
  }
}

TEST(TetGeneratorsTest, BallIsPositiveConformingAndRound) {
  auto b = MakeTetBall({0.05, 8});
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_TRUE(Validate(*b, 0.0).ok());
  ExpectConforming(*b);
  EXPECT_EQ(b->TetCount(), 6 * 8 * 8 * 8);
  const double ball = 4.0 / 3.0 * std::numbers::pi * std::pow(0.05, 3);
  EXPECT_NEAR(Volume(*b) / ball, 1.0, 0.08);  // facets inscribed in the sphere
  const TriMesh surface = BoundarySurface(*b);
  for (const auto& t : surface.triangles)
    for (int v : t) EXPECT_NEAR(surface.positions[v].norm(), 0.05, 1e-12);
}

TEST(TetGeneratorsTest, BadParametersAreRejectedByName) {
  EXPECT_EQ(MakeTetCylinder({0.25, 0.04, 0.03, 0, 10}).error().field, "rings");
  EXPECT_EQ(MakeTetCylinder({0.25, 0.04, 0.03, 2, 0}).error().field, "layers");
  EXPECT_EQ(MakeTetCylinder({-1, 0.04, 0.03, 2, 2}).error().field, "length");
  EXPECT_EQ(MakeTetCylinder({0.25, 0.0, 0.03, 2, 2}).error().field, "radius");
  EXPECT_EQ(MakeTetBall({0.05, 3}).error().field, "cells");
  EXPECT_EQ(MakeTetBall({std::nan(""), 4}).error().field, "radius");
}

}  // namespace
}  // namespace vsurg::geometry
