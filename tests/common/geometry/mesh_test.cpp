#include "common/geometry/mesh.h"

#include <gtest/gtest.h>

namespace vsurg::geometry {
namespace {

TetMesh UnitTet() {
  TetMesh t;
  t.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  t.tetrahedra = {{0, 1, 2, 3}};
  return t;
}

TEST(MeshTest, TetVolumeIsOneSixthOfTheUnitCube) {
  const TetMesh t = UnitTet();
  EXPECT_DOUBLE_EQ(TetVolume(t, 0), 1.0 / 6.0);
  EXPECT_TRUE(Validate(t).ok());
}

TEST(MeshTest, InvertedAndFlatTetrahedraAreRejectedByIndex) {
  TetMesh t = UnitTet();
  t.tetrahedra[0] = {0, 2, 1, 3};  // swapped: negative volume
  Status s = Validate(t);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("tetrahedron 0 is inverted"), std::string::npos);
  t = UnitTet();
  t.positions[3] = Vec3(0.3, 0.3, 0);  // in the plane of the others
  s = Validate(t);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("degenerate"), std::string::npos);
}

TEST(MeshTest, BoundaryOfATetIsAClosedOutwardSurface) {
  const TriMesh s = BoundarySurface(UnitTet());
  ASSERT_EQ(s.TriangleCount(), 4);
  const TopologyReport r = CheckTopology(s);
  EXPECT_TRUE(r.Closed());
  EXPECT_TRUE(r.ConsistentlyOriented());
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_NEAR(SignedVolume(s), 1.0 / 6.0, 1e-15);
}

TEST(MeshTest, TwoTetsShareTheirCommonFace) {
  TetMesh t = UnitTet();
  t.positions.push_back(Vec3(1, 1, 1));
  t.tetrahedra.push_back({1, 2, 3, 4});  // the other side of face (1,2,3), positive
  ASSERT_TRUE(Validate(t).ok());
  const TriMesh s = BoundarySurface(t);
  EXPECT_EQ(s.TriangleCount(), 6);
  EXPECT_TRUE(CheckTopology(s).Closed());
  EXPECT_NEAR(SignedVolume(s), TetVolume(t, 0) + TetVolume(t, 1), 1e-15);
}

TEST(MeshTest, TopologyFindsBoundaryAndMisorientedEdges) {
  TriMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)};
  m.triangles = {{0, 1, 2}, {1, 3, 2}};
  TopologyReport r = CheckTopology(m);
  EXPECT_EQ(r.boundary_edges, 4);
  EXPECT_TRUE(r.ConsistentlyOriented());
  m.triangles[1] = {1, 2, 3};  // traverses the shared edge 1→2 in the same direction
  r = CheckTopology(m);
  EXPECT_FALSE(r.ConsistentlyOriented());
}

TEST(MeshTest, ValidateRejectsBadIndicesRepeatsAndNonFinitePositions) {
  TriMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.triangles = {{0, 1, 3}};
  EXPECT_FALSE(Validate(m).ok());
  m.triangles = {{0, 1, 1}};
  EXPECT_FALSE(Validate(m).ok());
  m.triangles = {{0, 1, 2}};
  EXPECT_TRUE(Validate(m).ok());
  m.positions[2].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(Validate(m).ok());
}

TEST(MeshTest, AdjacencyIsSymmetricAndSorted) {
  TriMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)};
  m.triangles = {{0, 1, 2}, {1, 3, 2}};
  const VertexAdjacency adj = BuildVertexAdjacency(m);
  EXPECT_EQ(adj.Degree(0), 2);
  EXPECT_EQ(adj.Degree(1), 3);
  EXPECT_EQ(adj.Degree(2), 3);
  EXPECT_EQ(adj.Degree(3), 2);
  for (int v = 0; v < 4; ++v) {
    for (int k = adj.offsets[v]; k < adj.offsets[v + 1]; ++k) {
      const int w = adj.neighbours[k];
      EXPECT_TRUE(std::binary_search(adj.neighbours.begin() + adj.offsets[w],
                                     adj.neighbours.begin() + adj.offsets[w + 1], v));
    }
  }
  EXPECT_EQ(UniqueEdges(m).size(), 5u);
}

TEST(MeshTest, VertexNormalsAreUnitAndFaceTheRightWay) {
  TriMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.triangles = {{0, 1, 2}};
  ComputeVertexNormals(m);
  for (const Vec3& n : m.normals) EXPECT_NEAR((n - Vec3(0, 0, 1)).norm(), 0, 1e-15);
  EXPECT_DOUBLE_EQ(TriangleArea(m, 0), 0.5);
}

}  // namespace
}  // namespace vsurg::geometry
