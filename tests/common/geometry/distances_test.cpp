#include "common/geometry/distances.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::geometry {
namespace {

TEST(CentrelineTest, ProjectionGivesArcLengthFootAndTangent) {
  // An L-shaped polyline: along x to (1,0,0), then along y to (1,1,0).
  const std::vector<Vec3> line = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)};
  EXPECT_EQ(ArcLengths(line), (std::vector<double>{0, 1, 2}));
  auto p = ProjectOntoPolyline({Vec3(0.25, 0.3, 0), Vec3(1.2, 0.5, 0.1), Vec3(-1, 0, 0)}, line);
  ASSERT_TRUE(p.ok());
  EXPECT_DOUBLE_EQ((*p)[0].s, 0.25);
  EXPECT_EQ((*p)[0].point, Vec3(0.25, 0, 0));
  EXPECT_EQ((*p)[0].tangent, Vec3(1, 0, 0));
  EXPECT_DOUBLE_EQ((*p)[1].s, 1.5);
  EXPECT_EQ((*p)[1].tangent, Vec3(0, 1, 0));
  EXPECT_DOUBLE_EQ((*p)[2].s, 0.0);  // clamped to the first end
}

// Many points at once (segments made ahead) land where one point at a time does: a bent, unevenly
// sampled centreline with a repeated direction, points on both sides, past both ends and on it.
TEST(CentrelineTest, ManyPointsProjectAsOnePointAtATime) {
  std::vector<Vec3> line;
  double t = 0;
  for (int i = 0; i <= 40; ++i, t += i % 3 == 0 ? 0.021 : 0.017)
    line.push_back(Vec3(0.1 * std::sin(4 * t), 0.05 * t * t, t));
  std::vector<Vec3> points;
  for (int k = 0; k < 2000; ++k) {
    const double z = -0.1 + 0.9 * k / 1999.0, a = 0.37 * k;
    points.push_back(
        Vec3(0.1 * std::sin(4 * z) + 0.03 * std::cos(a), 0.05 * z * z + 0.03 * std::sin(a), z));
  }
  auto p = ProjectOntoPolyline(points, line);
  ASSERT_TRUE(p.ok());
  for (size_t k = 0; k < points.size(); ++k) {
    const CentrelineProjection one = ProjectPointOntoPolyline(line, points[k]);
    EXPECT_NEAR((*p)[k].s, one.s, 1e-12) << k;
    EXPECT_LT(((*p)[k].point - one.point).norm(), 1e-12) << k;
    EXPECT_LT(((*p)[k].tangent - one.tangent).norm(), 1e-12) << k;
  }
}

TEST(CentrelineTest, DegeneratePolylinesAreRejected) {
  EXPECT_FALSE(ProjectOntoPolyline({Vec3::Zero()}, {Vec3::Zero()}).ok());
  EXPECT_FALSE(ProjectOntoPolyline({Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}).ok());
}

TEST(ClosestPointTest, FindsTheFootOnASphere) {
  auto s = MakeSubdividedSphere({1.0, 4, SphereBase::kIcosahedron, Vec3::Zero()});
  ASSERT_TRUE(s.ok());
  auto sp = ClosestSurfacePoint(*s, Vec3(0, 0, 2));
  ASSERT_TRUE(sp.ok());
  EXPECT_NEAR(PositionOf(*s, *sp).z(), 1.0, 0.01);
  EXPECT_NEAR(sp->barycentric.sum(), 1.0, 1e-12);
  EXPECT_GT(NormalOf(*s, *sp).z(), 0.99);
}

// Exact geodesic on a sphere of radius R from the pole p: R·acos(x·p / R²).
double GreatCircle(const Vec3& x, const Vec3& p, double r) {
  return r * std::acos(std::clamp(x.dot(p) / (r * r), -1.0, 1.0));
}

struct Errors {
  double mean_rel = 0, max_rel = 0;
};

Errors GeodesicErrors(GeodesicMethod method, int levels) {
  const double r = 0.05;
  auto s = MakeSubdividedSphere({r, levels, SphereBase::kIcosahedron, Vec3::Zero()});
  auto sp = ClosestSurfacePoint(*s, Vec3(0.01, 0.02, 1.0));
  const Vec3 src = PositionOf(*s, *sp);
  auto d = GeodesicDistances(*s, *sp, method);
  EXPECT_TRUE(d.ok());
  Errors e;
  int n = 0;
  for (int v = 0; v < s->VertexCount(); ++v) {
    const double exact = GreatCircle(s->positions[v], src.normalized() * r, r);
    if (exact < 0.2 * r || exact > 2.5 * r) continue;  // away from the source and its antipode
    const double rel = std::abs((*d)[v] - exact) / exact;
    e.mean_rel += rel;
    e.max_rel = std::max(e.max_rel, rel);
    ++n;
  }
  e.mean_rel /= n;
  return e;
}

TEST(GeodesicTest, HeatMethodIsAccurateAndBeatsDijkstraOnASphere) {
  const Errors heat = GeodesicErrors(GeodesicMethod::kHeat, 4);
  const Errors dijkstra = GeodesicErrors(GeodesicMethod::kDijkstra, 4);
  EXPECT_LT(heat.mean_rel, 0.02);
  EXPECT_LT(heat.mean_rel, dijkstra.mean_rel);
  EXPECT_GT(dijkstra.mean_rel, 0.01);  // the edge graph's metric distortion is real
}

TEST(GeodesicTest, HeatMethodConvergesUnderRefinement) {
  EXPECT_LT(GeodesicErrors(GeodesicMethod::kHeat, 5).mean_rel,
            GeodesicErrors(GeodesicMethod::kHeat, 3).mean_rel);
}

// A flat square grid, each cell split along one diagonal: the true geodesic is the Euclidean
// distance in the plane.
TriMesh FlatGrid(int n, double size) {
  TriMesh m;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.positions.emplace_back(size * i / n, size * j / n, 0);
  }
  auto v = [n](int i, int j) { return j * (n + 1) + i; };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      m.triangles.push_back({v(i, j), v(i + 1, j), v(i + 1, j + 1)});
      m.triangles.push_back({v(i, j), v(i + 1, j + 1), v(i, j + 1)});
    }
  }
  return m;
}

TEST(GeodesicTest, OnAPlaneDijkstraIsNeverShortAndHeatIsClose) {
  const int n = 40;
  const TriMesh grid = FlatGrid(n, 0.1);
  // Source at the centre vertex, as a corner of a triangle that has it.
  const int centre = (n / 2) * (n + 1) + n / 2;
  SurfacePoint sp;
  for (int t = 0; t < grid.TriangleCount() && sp.triangle < 0; ++t) {
    for (int k = 0; k < 3; ++k) {
      if (grid.triangles[t][k] == centre) {
        sp.triangle = t;
        sp.barycentric = Vec3::Zero();
        sp.barycentric[k] = 1;
      }
    }
  }
  auto dijkstra = GeodesicDistances(grid, sp, GeodesicMethod::kDijkstra);
  auto heat = GeodesicDistances(grid, sp, GeodesicMethod::kHeat);
  ASSERT_TRUE(dijkstra.ok());
  ASSERT_TRUE(heat.ok());
  double worst_heat = 0, worst_dijkstra = 0;
  for (int v = 0; v < grid.VertexCount(); ++v) {
    const double exact = (grid.positions[v] - grid.positions[centre]).norm();
    EXPECT_GE((*dijkstra)[v], exact - 1e-12);     // a path on the mesh is never shorter
    if (exact < 0.01 || exact > 0.035) continue;  // away from the source and the border
    worst_heat = std::max(worst_heat, std::abs((*heat)[v] - exact) / exact);
    worst_dijkstra = std::max(worst_dijkstra, std::abs((*dijkstra)[v] - exact) / exact);
  }
  EXPECT_EQ((*dijkstra)[centre], 0.0);
  std::printf("worst relative error: heat %.4f, dijkstra %.4f\n", worst_heat, worst_dijkstra);
  EXPECT_LT(worst_heat, 0.1);
  EXPECT_GT(worst_dijkstra, 0.3);  // edge paths zig-zag off the grid's directions (√2 − 1 at worst)
  EXPECT_LT(worst_heat, 0.25 * worst_dijkstra);
}

TEST(GeodesicTest, OtherComponentsAreInfinitelyFar) {
  auto a = MakeSubdividedSphere({1.0, 2, SphereBase::kOctahedron, Vec3::Zero()});
  auto b = MakeSubdividedSphere({1.0, 2, SphereBase::kOctahedron, Vec3(5, 0, 0)});
  TriMesh both = *a;
  const int offset = both.VertexCount();
  for (const Vec3& p : b->positions) both.positions.push_back(p);
  for (Triangle t : b->triangles)
    both.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  for (GeodesicMethod m : {GeodesicMethod::kDijkstra, GeodesicMethod::kHeat}) {
    auto d = GeodesicDistances(both, SurfacePoint{0, Vec3(1, 0, 0)}, m);
    ASSERT_TRUE(d.ok());
    for (int v = 0; v < both.VertexCount(); ++v) {
      EXPECT_EQ(std::isinf((*d)[v]), v >= offset) << v;
    }
  }
}

TEST(GeodesicTest, BadSourcesAreRejected) {
  auto s = MakeSubdividedSphere({});
  EXPECT_FALSE(GeodesicDistances(*s, SurfacePoint{-1, Vec3(1, 0, 0)}, GeodesicMethod::kHeat).ok());
  EXPECT_FALSE(GeodesicDistances(*s, SurfacePoint{0, Vec3(2, 0, 0)}, GeodesicMethod::kHeat).ok());
  EXPECT_FALSE(
      GeodesicDistances(*s, SurfacePoint{0, Vec3(NAN, 0, 1)}, GeodesicMethod::kDijkstra).ok());
}

}  // namespace
}  // namespace vsurg::geometry
