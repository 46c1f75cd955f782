#include "common/geometry/obj_io.h"

#include <cstdio>
#include <filesystem>
#include <sstream>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"
#include "tests/support/temp_dir.h"

namespace vsurg::geometry {
namespace {

Expected<TriMesh> Parse(const std::string& text) {
  std::istringstream in(text);
  return ParseObj(in, "test.obj");
}

std::string ErrorOf(const std::string& text) {
  auto m = Parse(text);
  EXPECT_FALSE(m.ok()) << "expected an error for:\n" << text;
  return m.ok() ? "" : m.error().message;
}

TEST(ObjIoTest, RoundTripKeepsPositionsAndFaces) {
  auto sphere = MakeSubdividedSphere({0.05, 3, SphereBase::kOctahedron, Vec3(0.01, 0.02, 0.03)});
  ASSERT_TRUE(sphere.ok());
  const test::TempDir tmp("obj");
  const std::string path = (tmp / "roundtrip.obj").string();
  ASSERT_TRUE(WriteObj(*sphere, path, "round trip").ok());
  auto back = ReadObj(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->VertexCount(), sphere->VertexCount());
  ASSERT_EQ(back->triangles, sphere->triangles);
  for (int v = 0; v < sphere->VertexCount(); ++v) {
    // %.9g keeps 9 significant digits: below a nanometre at these sizes.
    EXPECT_NEAR((back->positions[v] - sphere->positions[v]).norm(), 0, 1e-10);
  }
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

TEST(ObjIoTest, AcceptsTheCommonFaceFormsNegativeIndicesAndPolygons) {
  auto m = Parse(
      "# a quad and a triangle\n"
      "o thing\nmtllib x.mtl\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\r\n"
      "vn 0 0 1\nvt 0 0\n"
      "usemtl skin\ns off\n"
      "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
      "v 0.5 0.5 1.0 1.0\n"
      "f -1//1 1//1 2//1   # trailing comment\n");
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->VertexCount(), 5);
  ASSERT_EQ(m->TriangleCount(), 3);  // quad fanned into two
  EXPECT_EQ(m->triangles[1], (Triangle{0, 2, 3}));
  EXPECT_EQ(m->triangles[2], (Triangle{4, 0, 1}));
}

TEST(ObjIoTest, HomogeneousWeightDividesTheCoordinates) {
  auto m = Parse("v 2 4 6 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->positions[0], Vec3(1, 2, 3));
}

TEST(ObjIoTest, MalformedFilesGiveLineAndReason) {
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0\n"),
            "test.obj:2: vertex needs 3 coordinates (optionally w), got 2");
  EXPECT_EQ(ErrorOf("v 0 0 zero\n"), "test.obj:1: vertex coordinate 'zero' is not a number");
  EXPECT_EQ(ErrorOf("v 0 0 nan\n"), "test.obj:1: vertex coordinate is not finite");
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"),
            "test.obj:4: face index 4 is out of range (3 vertices so far)");
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
            "test.obj:4: face index 0 is invalid (OBJ indices start at 1)");
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0 0\nf 1 2\n"), "test.obj:3: face needs at least 3 vertices");
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n"), "test.obj:4: face repeats vertex 2");
  EXPECT_EQ(ErrorOf("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n"),
            "test.obj:4: face vertex 'x' is not an index");
  EXPECT_EQ(ErrorOf("v 0 0 0\nbogus 1 2\n"), "test.obj:2: unknown statement 'bogus'");
  EXPECT_EQ(ErrorOf("v 0 0 0 0\n"), "test.obj:1: vertex weight w is zero");
  EXPECT_EQ(ErrorOf("v 0 0 0\n"), "test.obj: no faces in the file");
  EXPECT_EQ(ErrorOf(""), "test.obj: no faces in the file");
  EXPECT_EQ(ErrorOf("v 0 0 0\nf " + std::string(70000, '1') + "\n"),
            "test.obj:2: line longer than 65536 characters");
}

TEST(ObjIoTest, MissingFileAndUnwritablePathAreIoErrors) {
  auto m = ReadObj("/nonexistent/dir/mesh.obj");
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().code, ErrorCode::kIoError);
  EXPECT_NE(m.error().message.find("/nonexistent/dir/mesh.obj: cannot open"), std::string::npos);
  auto sphere = MakeSubdividedSphere({});
  Status s = WriteObj(*sphere, "/nonexistent/dir/out.obj");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kIoError);
}

}  // namespace
}  // namespace vsurg::geometry
