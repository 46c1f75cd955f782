// The imported-mesh scene (scenes/kidney-palpation.json): a closed organ-like surface made here,
// written as binary STL in millimetres the way 3D Slicer exports a segmentation, read back
// through assimp, tetrahedralised by CGAL, and palpated through the reduced contact model. The
// shipped scenes/kidney.stl is this generator's output (checked below), so the repository holds
// no third-party data; VSURG_WRITE_ORGAN=1 rewrites it.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"
#include "common/geometry/mesh_import.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/sim/visual_model.h"
#include "tests/support/temp_dir.h"

namespace vsurg::sim::organ_scene_test {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

// A kidney-like bean, millimetres: an ellipsoid of semi-axes 55 × 30 × 25 mm whose −y side is
// drawn in around its middle (the hilum). Every point moves along its own ray from the centre,
// so the surface stays star-shaped: closed, oriented, never crossing itself.
geometry::TriMesh Kidney() {
  auto s = geometry::MakeSubdividedSphere({1.0, 4, geometry::SphereBase::kOctahedron});
  geometry::TriMesh m = *s;
  for (Vec3& p : m.positions) {
    const double dent = p.y() < 0 ? 0.45 * std::exp(-(p.x() * p.x() + p.z() * p.z()) / 0.25) : 0;
    p = Vec3(55 * p.x(), 30 * p.y() * (1 - dent * -p.y()), 25 * p.z());
  }
  return m;
}

void WriteBinaryStl(const geometry::TriMesh& m, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  const std::string header = "vsurg kidney, mm (tests/common/sim/organ_scene_test.cpp)";
  out << header << std::string(80 - header.size(), ' ');
  const uint32_t n = static_cast<uint32_t>(m.TriangleCount());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : m.triangles) {
    float v[12] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) v[3 + 3 * k + c] = static_cast<float>(m.positions[t[k]][c]);
    out.write(reinterpret_cast<const char*>(v), sizeof v);
    out.write("\0\0", 2);
  }
}

TEST(OrganSceneTest, TheShippedKidneyIsThisGeneratorsOutput) {
  const fs::path shipped = fs::path(ScenesDirectory()) / "kidney.stl";
  if (const char* w = std::getenv("VSURG_WRITE_ORGAN"); w && std::string(w) == "1")
    WriteBinaryStl(Kidney(), shipped.string());
  const geometry::TriMesh made = Kidney();
  auto read = geometry::ImportSurfaceMesh(shipped.string(), 0.001);
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->VertexCount(), made.VertexCount());
  ASSERT_EQ(read->TriangleCount(), made.TriangleCount());
  // Same vertices (in the file's order after assimp joins the facets' copies), to float.
  double worst = 0;
  for (const Vec3& p : read->positions) {
    double best = 1e9;
    for (const Vec3& q : made.positions) best = std::min(best, (1e-3 * q - p).norm());
    worst = std::max(worst, best);
  }
  EXPECT_LT(worst, 1e-8);
  EXPECT_TRUE(geometry::CheckTopology(*read).Closed());
  EXPECT_GT(geometry::SignedVolume(*read), 0);  // outward
}

TEST(OrganSceneTest, TheKidneyIsTetrahedralisedAndSinksUnderThePress) {
  const test::TempDir dir("kidney");
  auto scene = LoadSceneByName("kidney-palpation");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->mesh.kind, MeshKind::kFile);
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  EXPECT_TRUE(fs::exists(dir / "kidney-palpation-contact.vrm"));
  const auto& rest = (*sim)->rest_mesh().positions;
  int top = 0;
  for (int i = 0; i < static_cast<int>(rest.size()); ++i)
    if (rest[i].z() > rest[top].z()) top = i;
  haptics::StylusSample s;
  s.position = rest[top] + Vec3(0.0003, 0.0002, 0.01);
  double t = 0;
  for (int i = 0; i < 100; ++i)
    s.time = (t += 1e-3), (*sim)->OnStylus(s), (*sim)->StepDeformation();
  haptics::ForceCommand c;
  for (int i = 0; i < 800; ++i) {
    s.time = (t += 1e-3);
    s.position.z() = std::max(rest[top].z() - 0.004, s.position.z() - 1e-4);
    c = (*sim)->OnStylus(s);
    (*sim)->StepDeformation();
  }
  ASSERT_TRUE(c.contact);
  ASSERT_TRUE(c.force.allFinite());
  EXPECT_GT(c.force.z(), 0.05);
  VisualFrame frame;
  ASSERT_TRUE((*sim)->TakeVisualFrame(frame));
  double top_dz = 0;
  for (size_t k = 0; k < frame.indices.size(); ++k)
    if (frame.indices[k] == top) top_dz = frame.positions[k].z() - rest[top].z();
  EXPECT_LT(top_dz, -0.0005);
  EXPECT_GT(top_dz, -0.004 - 1e-9);
}

TEST(OrganSceneTest, AVisualSurfaceCanBeAFileAndIsCarriedByThePhysicsOne) {
  // The scene names its visual surface: here the kidney's own file, so every fine vertex lies
  // on the physics surface and the mapping reproduces it at rest and moves it with it.
  auto scene = LoadSceneByName("kidney-palpation");
  ASSERT_TRUE(scene.ok());
  auto mesh = BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok());
  scene->visual.mesh = scene->mesh.path;
  scene->visual.metres_per_unit = scene->mesh.metres_per_unit;
  auto visual = BuildVisualModel(*scene, mesh->surface);
  ASSERT_TRUE(visual.ok()) << visual.error().message;
  EXPECT_EQ(visual->surface.VertexCount(), mesh->surface.VertexCount());
  EXPECT_EQ(visual->material, VisualMaterial::kKidney);
  EXPECT_EQ(visual->instrument, Instrument::kProbe);
  EXPECT_LT(visual->mapping.max_normal_offset(), 1e-6);
  geometry::TriMesh moved = mesh->surface;
  for (Vec3& p : moved.positions) p += Vec3(0.01, -0.02, 0.005);
  geometry::ComputeVertexNormals(moved);
  std::vector<Eigen::Vector3f> fine;
  visual->mapping.Apply(moved.positions, moved.normals, fine);
  double worst = 0;
  for (size_t i = 0; i < fine.size(); ++i)
    worst = std::max(
        worst,
        (fine[i].cast<double>() - visual->surface.positions[i] - Vec3(0.01, -0.02, 0.005)).norm());
  EXPECT_LT(worst, 1e-6);
  scene->visual.mesh = "/nonexistent/organ.stl";
  auto missing = BuildVisualModel(*scene, mesh->surface);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().field, "visual.mesh");
}

TEST(OrganSceneTest, ScriptedTraineesPalpateTheKidney) {
  // A scripted trainee for a mesh-file scene: the tool comes down above the organ's middle and
  // presses to the target depth; the good one completes and scores well, the rough one worse.
  const test::TempDir dir("kidney_t");
  auto scene = LoadSceneByName("kidney-palpation");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const auto play = [&](TraineeStyle style) {
    auto samples = ScriptedTrainee(*scene, style);
    EXPECT_TRUE(samples.ok()) << samples.error().message;
    auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = dir.string()});
    EXPECT_TRUE(sim.ok()) << sim.error().message;
    (*sim)->Replay(*samples, [](const haptics::StylusSample&, const haptics::ForceCommand& c) {
      ASSERT_TRUE(c.force.allFinite());
    });
    return (*sim)->Metrics();
  };
  const scoring::TrialMetrics good = play(TraineeStyle::kGood);
  EXPECT_TRUE(good.completed);
  EXPECT_LT(good.task_error, scene->task.tolerance);
  EXPECT_GT(good.peak_force, 0.02);
  EXPECT_GE(good.score, 7.0);
  const scoring::TrialMetrics rough = play(TraineeStyle::kRough);
  EXPECT_LT(rough.score, good.score - 2.0);
}

}  // namespace
}  // namespace vsurg::sim::organ_scene_test
