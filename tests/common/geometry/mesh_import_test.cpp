#include "common/geometry/mesh_import.h"
#include "tests/support/temp_dir.h"

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace vsurg::geometry::mesh_import_test {
namespace {

namespace fs = std::filesystem;

class MeshImportTest : public ::testing::Test {
 protected:
  std::string Write(const std::string& name, const std::string& bytes) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }
  test::TempDir dir_{"import"};
};

double Area(const TriMesh& m) {
  double a = 0;
  for (int t = 0; t < m.TriangleCount(); ++t) a += TriangleArea(m, t);
  return a;
}

// The unit tetrahedron's four outward faces, scaled by `s`.
const double kTet[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const int kTetFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

std::string AsciiStl(double s) {
  std::string out = "solid tet\n";
  for (const auto& f : kTetFaces) {
    out += "facet normal 0 0 0\n outer loop\n";
    for (int k : f)
      out += "  vertex " + std::to_string(s * kTet[k][0]) + " " + std::to_string(s * kTet[k][1]) +
             " " + std::to_string(s * kTet[k][2]) + "\n";
    out += " endloop\nendfacet\n";
  }
  return out + "endsolid tet\n";
}

std::string BinaryStl(double s) {
  std::string out(80, ' ');
  const uint32_t n = 4;
  out.append(reinterpret_cast<const char*>(&n), 4);
  for (const auto& f : kTetFaces) {
    float v[12] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) v[3 + 3 * k + c] = static_cast<float>(s * kTet[f[k]][c]);
    out.append(reinterpret_cast<const char*>(v), sizeof v);
    out.append(2, '\0');
  }
  return out;
}

TEST_F(MeshImportTest, ObjWithColoursSignedNumbersAndAConcavePolygon) {
  // 3D Slicer and scanners write vertex colours; "+4" is a valid number; the chevron is concave
  // at (2, 1) (a fan from its first vertex would cover area outside it: 10 instead of 8);
  // "f 1 2 2" repeats a vertex. (assimp 5.2's ear clipping accepts an ear whose edge passes
  // exactly through another vertex, e.g. an L-shaped hexagon started at its corner: a
  // degenerate case scans do not produce.)
  const std::string path = Write("chevron.obj",
                                 "# a chevron\n"
                                 "v 0 0 0 1 0 0\nv 4 0 0 1 0 0\nv +4 3 0 0 1 0\n"
                                 "v 2 1 0 0 1 0\nv 0 3 0 0 0 1\n"
                                 "f 1 2 3 4 5\nf 1 2 2\n");
  ImportReport report;
  auto m = ImportSurfaceMesh(path, 1.0, &report);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->TriangleCount(), 3);
  EXPECT_NEAR(Area(*m), 8.0, 1e-12);
  EXPECT_GE(report.dropped_faces, 1);
}

// A closed cube whose faces are three OBJ groups: the groups' seams are welded (8 vertices, a
// closed surface, not three patches of 16), and each group names its vertices; two ASCII STL
// solids are two groups likewise.
TEST_F(MeshImportTest, NamedGroupsShareTheirSeamsAndNameTheirVertices) {
  const std::string cube =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
      "g base\nf 1 3 2\nf 1 4 3\n"
      "g sides\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n"
      "g top\nf 5 6 7\nf 5 7 8\n";
  ImportReport report;
  auto m = ImportSurfaceMesh(Write("cube.obj", cube), 1.0, &report);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->VertexCount(), 8);
  EXPECT_EQ(m->TriangleCount(), 12);
  EXPECT_TRUE(CheckTopology(*m).Closed());
  EXPECT_NEAR(SignedVolume(*m), 1.0, 1e-12);
  ASSERT_EQ(report.groups.size(), 3u);
  ASSERT_EQ(report.groups["base"].size(), 4u);
  for (int v : report.groups["base"]) EXPECT_EQ(m->positions[v].z(), 0.0);
  ASSERT_EQ(report.groups["top"].size(), 4u);
  for (int v : report.groups["top"]) EXPECT_EQ(m->positions[v].z(), 1.0);
  EXPECT_EQ(report.groups["sides"].size(), 8u);  // every vertex: the seams are shared
  const std::string solids =
      "solid base\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 1 0 0\n"
      "endloop\nendfacet\nendsolid base\nsolid lid\nfacet normal 0 0 1\nouter loop\n"
      "vertex 0 0 0\nvertex 1 0 0\nvertex 1 1 1\nendloop\nendfacet\nendsolid lid\n";
  auto two = ImportSurfaceMesh(Write("two.stl", solids), 1.0, &report);
  ASSERT_TRUE(two.ok()) << two.error().message;
  EXPECT_EQ(two->VertexCount(), 4);  // two shared corners
  EXPECT_EQ(report.groups["base"].size(), 3u);
  EXPECT_EQ(report.groups["lid"].size(), 3u);
}

TEST_F(MeshImportTest, SlicerStlInMillimetresAsciiAndBinary) {
  for (const auto& [name, bytes] : {std::pair{std::string("a.stl"), AsciiStl(10)},
                                    std::pair{std::string("b.stl"), BinaryStl(10)}}) {
    SCOPED_TRACE(name);
    auto m = ImportSurfaceMesh(Write(name, bytes), *UnitScale("mm"));
    ASSERT_TRUE(m.ok()) << m.error().message;
    EXPECT_EQ(m->VertexCount(), 4);  // STL repeats each vertex per facet: joined
    EXPECT_EQ(m->TriangleCount(), 4);
    EXPECT_TRUE(CheckTopology(*m).Closed());
    EXPECT_NEAR(SignedVolume(*m), std::pow(0.01, 3) / 6, 1e-12);  // 1 cm legs, in m³
  }
}

TEST_F(MeshImportTest, PlyAndGltf) {
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
      "property float z\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
      "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";
  auto cube = ImportSurfaceMesh(Write("cube.ply", ply), 0.01);
  ASSERT_TRUE(cube.ok()) << cube.error().message;
  EXPECT_EQ(cube->TriangleCount(), 12);
  EXPECT_NEAR(std::abs(SignedVolume(*cube)), 1e-6, 1e-15);
  // glTF 2 with its buffer inline (a data URI): one triangle.
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::string raw(reinterpret_cast<const char*>(xyz), sizeof xyz), b64;
  static const char* kB64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  for (size_t i = 0; i < raw.size(); i += 3) {
    uint32_t v = static_cast<uint8_t>(raw[i]) << 16;
    if (i + 1 < raw.size()) v |= static_cast<uint8_t>(raw[i + 1]) << 8;
    if (i + 2 < raw.size()) v |= static_cast<uint8_t>(raw[i + 2]);
    b64 += kB64[(v >> 18) & 63];
    b64 += kB64[(v >> 12) & 63];
    b64 += i + 1 < raw.size() ? kB64[(v >> 6) & 63] : '=';
    b64 += i + 2 < raw.size() ? kB64[v & 63] : '=';
  }
  const std::string gltf =
      R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
      R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":4}]}],)"
      R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",)"
      R"("min":[0,0,0],"max":[1,1,0]}],"bufferViews":[{"buffer":0,"byteLength":36}],)"
      R"("buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,)" +
      b64 + R"("}]})";
  auto tri = ImportSurfaceMesh(Write("tri.gltf", gltf), 1.0);
  ASSERT_TRUE(tri.ok()) << tri.error().message;
  EXPECT_EQ(tri->TriangleCount(), 1);
  EXPECT_NEAR(Area(*tri), 0.5, 1e-7);
}

TEST_F(MeshImportTest, BrokenFilesGetAClearErrorNamingTheFile) {
  const auto expect_error = [&](const std::string& name, const std::string& bytes,
                                const std::string& says) {
    const std::string path = Write(name, bytes);
    auto m = ImportSurfaceMesh(path);
    ASSERT_FALSE(m.ok()) << name;
    EXPECT_EQ(m.error().message.rfind(path, 0), 0u) << m.error().message;
    EXPECT_NE(m.error().message.find(says), std::string::npos) << m.error().message;
  };
  expect_error("empty.obj", "", "");
  expect_error("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces");
  // An OBJ that assimp refuses gets the line and the reason (assimp says neither: "vertex index
  // out of range" for a bad number too), then assimp's own words.
  expect_error("range.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n",
               ":3: face index 7 is out of range (2 vertices so far) (assimp: ");
  expect_error("number.obj", "v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n",
               ":2: vertex coordinate 'x' is not a number");
  auto memory = ImportSurfaceMeshFromMemory("v 0 0 0\nf 1 2 3\n", 16, "obj", "upload.obj");
  ASSERT_FALSE(memory.ok());
  EXPECT_EQ(memory.error().message.rfind("upload.obj:2: face index 2 is out of range", 0), 0u)
      << memory.error().message;
  expect_error("short.stl", std::string(84, '\0') + "garbage", "");
  auto missing = ImportSurfaceMesh((dir_ / "none.stl").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_FALSE(UnitScale("inch").ok());
  EXPECT_FALSE(ImportSurfaceMesh(Write("ok.stl", AsciiStl(1)), -1.0).ok());
}

}  // namespace
}  // namespace vsurg::geometry::mesh_import_test
