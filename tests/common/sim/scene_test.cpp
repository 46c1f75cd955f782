#include "common/sim/scene.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/geometry/mesh_generators.h"
#include "common/sim/limb_scene.h"
#include "common/sim/rooms/room_support.h"
#include "common/sim/simulation.h"
#include "tests/support/temp_dir.h"

namespace vsurg::sim {
namespace {

TEST(SceneTest, EveryShippedSceneLoads) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(ScenesDirectory())) {
    if (entry.path().extension() != ".json") continue;
    auto scene = LoadScene(entry.path().string());
    EXPECT_TRUE(scene.ok()) << (scene.ok() ? "" : scene.error().message);
    if (scene.ok()) {
      EXPECT_EQ(scene->name + ".json", entry.path().filename().string());
    }
    ++count;
  }
  EXPECT_GE(count, 6);
}

TEST(SceneTest, ArmAndCalfFilesMatchTheBuiltInDefaults) {
  for (const auto& [file, builtin] :
       {std::pair{"arm-torsion", "arm"}, std::pair{"calf-torsion", "calf"}}) {
    auto scene = LoadSceneByName(file);
    auto limb = BuiltinLimbScene(builtin);
    ASSERT_TRUE(scene.ok() && limb.ok());
    const tissue::CoilSpringParams& a = scene->region.coil;
    const tissue::CoilSpringParams& b = limb->coil;
    EXPECT_EQ(a.core_radius, b.core_radius);
    EXPECT_EQ(a.thickness, b.thickness);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.coils, b.coils);
    EXPECT_EQ(a.modulus, b.modulus);
    EXPECT_NEAR(a.max_force, b.max_force, 1e-15);
    EXPECT_EQ(scene->mesh.limb.length, limb->limb.length);
  }
}

// arm-torsion carries the per-ring fit with the capacity kept (`vsurg-sim calibrate`'s line
// "per-ring, F_t held"): one rigidity per coil, growing outwards, the built-in arm's 3.3 N·m
// capacity, and 60° at the coil-spring paper's 2.07 N·m within the fit's curve error.
TEST(SceneTest, TheArmSceneCarriesPerCoilRigiditiesAndKeepsItsCapacity) {
  auto scene = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const tissue::CoilSpringParams& c = scene->region.coil;
  ASSERT_EQ(static_cast<int>(c.coil_rigidity.size()), c.coils);
  for (int i = 1; i < c.coils; ++i) EXPECT_GE(c.coil_rigidity[i], 0.95 * c.coil_rigidity[i - 1]);
  auto model = tissue::CoilSpringModel::Create(c);
  ASSERT_TRUE(model.ok());
  EXPECT_NEAR(model->Capacity(), 3.30, 1e-9);
  EXPECT_NEAR(model->Forward(2.07).total_twist, 60.0 * std::numbers::pi / 180, 0.1);
  for (int i = 1; i <= c.coils; ++i) EXPECT_EQ(model->CoilRigidity(i), c.coil_rigidity[i - 1]);
}

TEST(SceneTest, AMeshFileInMillimetresIsReadThroughAssimp) {
  // A 5 cm ball as 3D Slicer would export it: ASCII STL in millimetres, each facet's vertices
  // repeated.
  auto ball = geometry::MakeSubdividedSphere({50.0, 3, geometry::SphereBase::kOctahedron});
  ASSERT_TRUE(ball.ok());
  const test::TempDir dir("scene_ball");
  const std::string stl = (dir / "ball.stl").string();
  {
    std::ofstream out(stl);
    out << "solid ball\n";
    for (const auto& t : ball->triangles) {
      out << "facet normal 0 0 0\nouter loop\n";
      for (int v : t)
        out << "vertex " << ball->positions[v].x() << " " << ball->positions[v].y() << " "
            << ball->positions[v].z() << "\n";
      out << "endloop\nendfacet\n";
    }
    out << "endsolid ball\n";
  }
  const std::string text = R"({"name": "t", "mesh": {"type": "file", "path": ")" + stl +
                           R"(", "units": "mm"},
    "regions": [{"name": "r", "model": {"type": "mass-spring", "structural_stiffness": 50}}],
    "task": {"type": "press", "target_depth_m": 0.005, "tolerance_m": 0.001},
    "error_budget": {"rms": 0.2}})";
  auto scene = ParseScene(text, "x.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->mesh.kind, MeshKind::kFile);
  auto mesh = BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  EXPECT_EQ(mesh->surface.VertexCount(), ball->VertexCount());  // the STL's repeats joined
  double r = 0;
  for (const auto& p : mesh->surface.positions) r = std::max(r, p.norm());
  EXPECT_NEAR(r, 0.05, 1e-6);  // millimetres became metres
  auto bad = ParseScene(
      text.substr(0, text.find("\"mm\"")) + R"("inch"},)" + text.substr(text.find("\"mm\"") + 6),
      "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("mesh.units"), std::string::npos) << bad.error().message;
}

TEST(SceneTest, TaskAndModelAreRead) {
  auto arm = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(arm.ok());
  EXPECT_EQ(arm->region.kind, ModelKind::kCoil);
  EXPECT_NEAR(arm->task.target, 45 * M_PI / 180, 1e-12);
  EXPECT_NEAR(arm->task.tolerance, 5 * M_PI / 180, 1e-12);
  EXPECT_EQ(arm->haptics.device, "touch");
  auto sphere = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(sphere.ok());
  EXPECT_EQ(sphere->region.kind, ModelKind::kMassSpring);
  EXPECT_EQ(sphere->region.integrator, tissue::Integrator::kImplicitEuler);
  EXPECT_EQ(sphere->mesh.particles, 256);
  auto reduced = LoadSceneByName("sphere-palpation-1024");
  ASSERT_TRUE(reduced.ok());
  EXPECT_EQ(reduced->region.kind, ModelKind::kReduced);
  EXPECT_EQ(reduced->region.reduced.fem_cells, 8);
  EXPECT_DOUBLE_EQ(reduced->region.reduced.footprint_radius, 0.005);
  EXPECT_EQ(reduced->mesh.particles, 1024);
  EXPECT_EQ(sphere->task.kind, scoring::TaskKind::kPress);
}

// Positions compared as rounded keys (the OBJ text round-trips them to 6 digits).
using Vec3Key = std::array<long, 3>;
Vec3Key Key(const geometry::Vec3& p) {
  return {std::lround(p.x() * 1e5), std::lround(p.y() * 1e5), std::lround(p.z() * 1e5)};
}

std::string Minimal() {
  return R"({"name": "t", "mesh": {"type": "sphere", "radius": 0.05, "particles": 256},
    "regions": [{"name": "r", "model": {"type": "mass-spring", "structural_stiffness": 50}}],
    "task": {"type": "press", "target_depth_m": 0.005, "tolerance_m": 0.001},
    "error_budget": {"rms": 0.2}})";
}

std::string Field(const std::string& text) {
  auto s = ParseScene(text, "x.json");
  EXPECT_FALSE(s.ok()) << text;
  return s.ok() ? "" : s.error().message;
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

// The support as a named group of the file (an OBJ group "table" under a ball) or as a plane:
// the surface's held vertices are the group's (the plane's far side); the FEM's are its boundary
// vertices nearest a held surface vertex; a group the file lacks names the ones it has; a group
// on a built-in mesh, a zero normal and a support object of neither kind are refused.
TEST(SceneTest, ASupportCanBeANamedGroupOfTheFileOrAPlane) {
  auto ball = geometry::MakeSubdividedSphere({0.05, 3, geometry::SphereBase::kOctahedron});
  ASSERT_TRUE(ball.ok());
  const test::TempDir dir("scene_groups");
  const std::string obj = (dir / "groups.obj").string();
  std::set<int> table;
  {
    std::ofstream out(obj);
    for (const auto& p : ball->positions)
      out << "v " << p.x() << " " << p.y() << " " << p.z() << "\n";
    for (const bool low : {true, false}) {
      out << "g " << (low ? "table" : "organ") << "\n";
      for (const auto& t : ball->triangles) {
        const double z =
            (ball->positions[t[0]] + ball->positions[t[1]] + ball->positions[t[2]]).z() / 3;
        if ((z < -0.04) != low) continue;
        out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
        if (low) table.insert(t.begin(), t.end());
      }
    }
  }
  const std::string text = R"({"name": "t", "mesh": {"type": "file", "path": ")" + obj + R"("},
    "regions": [{"name": "r", "model": {"type": "reduced", "fem_size": 0.012,
                 "support": {"group": "table"}}}],
    "task": {"type": "press", "target_depth_m": 0.005, "tolerance_m": 0.001},
    "error_budget": {"rms": 0.2}})";
  auto scene = ParseScene(text, "x.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->region.support, Support::kGroup);
  auto mesh = BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  auto held = SupportedVertices(mesh->surface, scene->region, mesh->groups);
  ASSERT_TRUE(held.ok()) << held.error().message;
  std::set<Vec3Key> held_at, table_at;
  for (int v : *held) held_at.insert(Key(mesh->surface.positions[v]));
  for (int v : table) table_at.insert(Key(ball->positions[v]));
  EXPECT_EQ(held_at, table_at);
  geometry::TetMesh fem;
  fem.positions = mesh->surface.positions;  // a stand-in FEM: a fan of tets from the centre
  fem.positions.push_back(geometry::Vec3::Zero());
  for (const auto& t : mesh->surface.triangles)
    fem.tetrahedra.push_back({t[0], t[1], t[2], fem.VertexCount() - 1});
  const std::vector<int> fem_held = SupportedFemVertices(fem, mesh->surface, *held, scene->region);
  EXPECT_EQ(std::set<int>(fem_held.begin(), fem_held.end()),
            std::set<int>(held->begin(), held->end()));
  // A session builds on it (CGAL's tetrahedra held where the table group is), and a scene that
  // names a group the file lacks fails at Create, naming the field.
  const std::string cache = (dir / "cache").string();
  auto sim = Simulation::Create(*scene, {.threaded = false, .cache_dir = cache});
  ASSERT_TRUE(sim.ok()) << sim.error().message;
  auto wrong = ParseScene(Replace(text, R"("group": "table")", R"("group": "base")"), "x.json");
  ASSERT_TRUE(wrong.ok());
  auto refused = Simulation::Create(*wrong, {.threaded = false, .cache_dir = cache});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().field, "regions[0].model.support");
  RegionSpec other = scene->region;
  other.support_group = "base";
  auto missing = SupportedVertices(mesh->surface, other, mesh->groups);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("no group 'base' (it has: organ, table)"),
            std::string::npos)
      << missing.error().message;
  // A plane: everything at or below z = −3 cm, the normal pointing up into the free part.
  const std::string plane = Replace(text, R"({"group": "table"})",
                                    R"({"plane": {"point": [0, 0, -0.03], "normal": [0, 0, 2]}})");
  auto by_plane = ParseScene(plane, "x.json");
  ASSERT_TRUE(by_plane.ok()) << by_plane.error().message;
  auto below = SupportedVertices(mesh->surface, by_plane->region, mesh->groups);
  ASSERT_TRUE(below.ok());
  EXPECT_FALSE(below->empty());
  for (int v = 0; v < mesh->surface.VertexCount(); ++v)
    EXPECT_EQ(std::count(below->begin(), below->end(), v) == 1,
              mesh->surface.positions[v].z() <= -0.03)
        << v;
  EXPECT_NE(Field(Replace(plane, "[0, 0, 2]", "[0, 0, 0]")).find("support.plane.normal"),
            std::string::npos);
  EXPECT_NE(Field(Replace(plane, R"("point": [0, 0, -0.03], )", "")).find("support.plane.point"),
            std::string::npos);
  EXPECT_NE(Field(Replace(text, R"({"group": "table"})", R"({"edge": 1})")).find("support"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("structural_stiffness": 50)",
                          R"("structural_stiffness": 50, "support": {"group": "table"})"))
                .find("only a mesh file has named groups"),
            std::string::npos);
}

TEST(SceneTest, TheVisualMaterialIsReadWithADefaultByMesh) {
  auto organ = ParseScene(Minimal(), "x.json");
  ASSERT_TRUE(organ.ok());
  EXPECT_EQ(organ->visual.material, VisualMaterial::kOrgan);  // a sphere without "visual"
  auto kidney = ParseScene(Replace(Minimal(), R"("error_budget")",
                                   R"("visual": {"material": "kidney"}, "error_budget")"),
                           "x.json");
  ASSERT_TRUE(kidney.ok()) << kidney.error().message;
  EXPECT_EQ(kidney->visual.material, VisualMaterial::kKidney);
  EXPECT_EQ(LoadSceneByName("arm-torsion")->visual.material, VisualMaterial::kSkin);
  EXPECT_EQ(LoadSceneByName("kidney-palpation")->visual.material, VisualMaterial::kKidney);
  EXPECT_NE(Field(Replace(Minimal(), R"("error_budget")",
                          R"("visual": {"material": "marble"}, "error_budget")"))
                .find("visual.material: one of skin, organ, kidney"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("error_budget")",
                          R"("visual": {"min_triangles": 10}, "error_budget")"))
                .find("min_triangles"),
            std::string::npos);
  auto scanned =
      ParseScene(Replace(Minimal(), R"("error_budget")",
                         R"("visual": {"mesh": "organ.stl", "units": "mm"}, "error_budget")"),
                 "/scenes/x.json");
  ASSERT_TRUE(scanned.ok()) << scanned.error().message;
  EXPECT_EQ(scanned->visual.mesh, "/scenes/organ.stl");  // beside the scene file
  EXPECT_DOUBLE_EQ(scanned->visual.metres_per_unit, 1e-3);
  EXPECT_NE(Field(Replace(Minimal(), R"("error_budget")",
                          R"("visual": {"mesh": "o.stl", "units": "furlong"}, "error_budget")"))
                .find("visual.units"),
            std::string::npos);
}

TEST(SceneTest, BadScenesNameTheField) {
  ASSERT_TRUE(ParseScene(Minimal(), "x.json").ok())
      << ParseScene(Minimal(), "x.json").error().message;
  EXPECT_NE(Field("{ not json").find("x.json: not valid JSON"), std::string::npos);
  // A number beyond a double threw out_of_range past the parse_error catch (fuzz_scene_json).
  EXPECT_NE(Field(Replace(Minimal(), R"("radius": 0.05)", R"("radius": 1e400)"))
                .find("x.json: not valid JSON"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("name": "t", )", "")).find("x.json: name: is required"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("radius": 0.05)", R"("radius": "big")"))
                .find("mesh.radius: must be a number"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("particles": 256)", R"("particles": 2)"))
                .find("mesh.particles: must be in"),
            std::string::npos);
  // The contact in the station's model: the tissue's (viscoelastic) unless the scene asks else.
  using ContactModel = HapticsSpec::ContactModel;
  EXPECT_EQ(ParseScene(Minimal(), "x.json")->haptics.contact_model, ContactModel::kViscoelastic);
  const auto with_contact = [](const std::string& value) {
    return Replace(Minimal(), R"("error_budget")",
                   R"("haptics": {"contact_model": )" + value + R"(}, "error_budget")");
  };
  for (const auto& [name, model] :
       {std::pair{"fitted", ContactModel::kFitted}, std::pair{"proxy", ContactModel::kProxy},
        std::pair{"viscoelastic", ContactModel::kViscoelastic}}) {
    auto parsed = ParseScene(with_contact("\"" + std::string(name) + "\""), "x.json");
    ASSERT_TRUE(parsed.ok()) << parsed.error().message;
    EXPECT_EQ(parsed->haptics.contact_model, model) << name;
  }
  EXPECT_NE(Field(with_contact(R"("guessed")"))
                .find("haptics.contact_model: must be viscoelastic, fitted or proxy"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("type": "mass-spring")", R"("type": "magic")"))
                .find("regions[0].model.type: must be coil, mass-spring, ring-layer, reduced or "
                      "cut-membrane"),
            std::string::npos);
  // Reduced models: odd or out-of-range FEM cells, an unknown mode, a mesh that is no sphere.
  const std::string reduced =
      Replace(Minimal(), R"("type": "mass-spring", "structural_stiffness": 50)",
              R"("type": "reduced", "fem_cells": 8)");
  ASSERT_TRUE(ParseScene(reduced, "x.json").ok()) << ParseScene(reduced, "x.json").error().message;
  EXPECT_NE(Field(Replace(reduced, R"("fem_cells": 8)", R"("fem_cells": 7)")).find("must be even"),
            std::string::npos);
  EXPECT_NE(Field(Replace(reduced, R"("fem_cells": 8)", R"("fem_cells": 64)"))
                .find("regions[0].model.fem_cells: must be in"),
            std::string::npos);
  EXPECT_NE(Field(Replace(reduced, R"("fem_cells": 8)", R"("fem_cells": 8, "mode": "twist")"))
                .find("regions[0].model.mode"),
            std::string::npos);
  EXPECT_NE(Field(Replace(reduced, R"({"type": "sphere", "radius": 0.05, "particles": 256})",
                          R"({"type": "limb", "preset": "forearm"})"))
                .find("needs a sphere, a block or a closed mesh file"),
            std::string::npos);
  // Surface twist: on a sphere or a mesh file, with a twist task; jaws of 0.1 mm to 10 cm.
  const std::string forceps =
      Replace(Replace(reduced, R"("fem_cells": 8)", R"("fem_cells": 8, "mode": "surface-twist")"),
              R"("type": "press")", R"("type": "twist", "target_deg": 30, "tolerance_deg": 5)");
  ASSERT_TRUE(ParseScene(forceps, "x.json").ok()) << ParseScene(forceps, "x.json").error().message;
  EXPECT_EQ(ParseScene(forceps, "x.json")->region.reduced.mode, ReducedMode::kSurfaceTwist);
  EXPECT_NE(Field(Replace(forceps, R"("fem_cells": 8)", R"("fem_cells": 8, "jaw_radius": 1)"))
                .find("regions[0].model.jaw_radius: must be in"),
            std::string::npos);
  EXPECT_NE(Field(Replace(forceps, R"({"type": "sphere", "radius": 0.05, "particles": 256})",
                          R"({"type": "limb", "preset": "forearm"})"))
                .find("surface-twist model needs a sphere, a block or a closed mesh file"),
            std::string::npos);
  EXPECT_NE(Field(Replace(forceps, R"("type": "twist", "target_deg": 30, "tolerance_deg": 5)",
                          R"("type": "press")"))
                .find("task.type"),
            std::string::npos);
  EXPECT_NE(
      Field(Replace(Minimal(), R"("structural_stiffness": 50)", R"("structural_stiffness": -5)"))
          .find("regions[0].model.structural_stiffness"),
      std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("structural_stiffness": 50)",
                          R"("structural_stiffness": 50, "integrator": "euler")"))
                .find("regions[0].model.integrator"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("type": "press")", R"("type": "twist")"))
                .find("task.target_deg: is required"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("rms": 0.2)", R"("rms": -1)")).find("error_budget.rms"),
            std::string::npos);
  EXPECT_NE(Field(Replace(Minimal(), R"("regions": [)",
                          R"("regions": [{"model": {"type": "ring-layer"}}, )"))
                .find("regions: must be an array with exactly one"),
            std::string::npos);
  // Per-coil rigidities: one per coil, each a positive number.
  const std::string coil = Replace(
      Replace(
          Minimal(), R"("type": "mass-spring", "structural_stiffness": 50)",
          R"("type": "coil", "mode": "surface", "core_radius": 0.004, "thickness": 0.004, "width": 0.01, )"
          R"("coils": 3, "modulus": 1e8, "max_force": 0.1, "coil_rigidity": [1, 2, 3])"),
      R"("type": "press")", R"("type": "twist", "target_deg": 30, "tolerance_deg": 5)");
  ASSERT_TRUE(ParseScene(coil, "x.json").ok()) << ParseScene(coil, "x.json").error().message;
  EXPECT_EQ(ParseScene(coil, "x.json")->region.coil.coil_rigidity, (std::vector<double>{1, 2, 3}));
  EXPECT_NE(Field(Replace(coil, "[1, 2, 3]", "[1, 2]"))
                .find("regions[0].model.coil_rigidity: must be an array of 3 numbers"),
            std::string::npos);
  EXPECT_NE(Field(Replace(coil, "[1, 2, 3]", R"([1, -2, 3])"))
                .find("regions[0].model.coil_rigidity: [1] must be a number in"),
            std::string::npos);
  EXPECT_NE(Field(Replace(coil, "[1, 2, 3]", R"([1, "x", 3])")).find("coil_rigidity: [1]"),
            std::string::npos);
  EXPECT_NE(Field(Replace(coil, "[1, 2, 3]", "7")).find("coil_rigidity: must be an array"),
            std::string::npos);
  auto missing = LoadSceneByName("no-such-scene");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_FALSE(LoadSceneByName("../etc/passwd").ok());
}

// A description that was a number escaped as a JSON type_error ("internal error", exit 1) and in
// the server's scenes folder broke ListScenes and Create for everyone. Every field is checked.
// Inclusions: read into the scene for a reduced contact model, refused by name otherwise.
// The tissue's static curve under the proxy (`vsurg-sim contact-law`): read in metres and
// newtons; one that does not rise from (0, 0), has too many points or is no list of pairs is
// refused by name. The shipped sphere's curve is the one its station's surface carries.
TEST(SceneTest, TheTissueCurveIsReadAndABadOneNamed) {
  const auto with_curve = [](const std::string& value) {
    return Replace(Minimal(), R"("error_budget")",
                   R"("haptics": {"tissue_curve": )" + value + R"(}, "error_budget")");
  };
  auto parsed = ParseScene(with_curve("[[0.0002, 0.09], [0.001, 0.29]]"), "x.json");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->haptics.tissue_curve.count, 2);
  EXPECT_EQ(parsed->haptics.tissue_curve.yield[1], 0.001);
  EXPECT_EQ(parsed->haptics.tissue_curve.force[0], 0.09);
  EXPECT_EQ(ParseScene(Minimal(), "x.json")->haptics.tissue_curve.count, 0);
  std::string many = "[";
  for (int i = 1; i <= 17; ++i)
    many += (i > 1 ? ", [" : "[") + std::to_string(i * 1e-4) + ", " + std::to_string(i * 0.1) + "]";
  for (const std::string& bad :
       {std::string("[[0.001, 0.3], [0.002, 0.2]]"), std::string("[[0, 0], [0.001, 0.3]]"),
        std::string("[0.001, 0.3]"), std::string("[[0.001]]"), std::string("[]"),
        std::string("\"steep\""), many + "]"})
    EXPECT_NE(Field(with_curve(bad)).find("haptics.tissue_curve: must"), std::string::npos) << bad;
  auto sphere = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(sphere.ok());
  EXPECT_TRUE(sphere->haptics.tissue_curve.Valid());
}

TEST(SceneTest, InclusionsAreReadForAReducedModelAndBadOnesNamed) {
  const std::string reduced =
      Replace(Minimal(), R"("type": "mass-spring", "structural_stiffness": 50)",
              R"("type": "reduced", "fem_cells": 12)");
  const auto with = [&](const std::string& list, const std::string& base = "") {
    return Replace(base.empty() ? reduced : base, R"("error_budget")",
                   R"("tissue": {"inclusions": )" + list + R"(}, "error_budget")");
  };
  auto scene = ParseScene(with(R"([{"centre": [0, 0, 0.035], "radius": 0.005, "contrast": 5},
               {"centre": [0.02, 0, 0.01], "radius": 0.004, "contrast": 0.5}])"),
                          "x.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  ASSERT_EQ(scene->inclusions.size(), 2u);
  EXPECT_EQ(scene->inclusions[0].centre, Eigen::Vector3d(0, 0, 0.035));
  EXPECT_EQ(scene->inclusions[0].radius, 0.005);
  EXPECT_EQ(scene->inclusions[1].contrast, 0.5);
  const std::pair<const char*, const char*> bad[] = {
      {R"([{"centre": [0, 0, 0], "radius": 0, "contrast": 5}])", "tissue.inclusions[0].radius"},
      {R"([{"centre": [0, 0, 0], "radius": -0.01, "contrast": 5}])", "tissue.inclusions[0].radius"},
      {R"([{"centre": [0, 0, 0], "radius": 0.01, "contrast": 0}])",
       "tissue.inclusions[0].contrast"},
      {R"([{"centre": [0, 0, 0], "radius": 0.01, "contrast": 1000}])",
       "tissue.inclusions[0].contrast"},
      {R"([{"centre": [0, 0, 0], "radius": 0.01, "contrast": "hard"}])",
       "tissue.inclusions[0].contrast"},
      {R"([{"centre": [0, 0], "radius": 0.01, "contrast": 5}])", "tissue.inclusions[0].centre"},
      {R"([{"radius": 0.01, "contrast": 5}])", "tissue.inclusions[0].centre"},
      {R"([{"centre": [0, 0, 0.06], "radius": 0.01, "contrast": 5}])",
       "tissue.inclusions[0].centre: lies outside the tissue"},
      {R"([{"centre": [0, 0, 0], "radius": 0.01, "contrast": 5}, 3])", "tissue.inclusions[1]"},
      {R"({"centre": [0, 0, 0]})", "tissue.inclusions: must be an array"},
  };
  for (const auto& [list, field] : bad)
    EXPECT_NE(Field(with(list)).find(field), std::string::npos)
        << list << ": " << Field(with(list));
  // A model without an FEM behind it has no inclusions to carry.
  EXPECT_NE(Field(with(R"([{"centre": [0, 0, 0], "radius": 0.01, "contrast": 5}])", Minimal()))
                .find("tissue.inclusions: only a reduced contact or surface-twist model"),
            std::string::npos);
}

// Where the volume constraint is integrated: "element" (the default) or "vertices", for a reduced
// model's tables only; anything else refused by name.
TEST(SceneTest, TheVolumeAtTheVerticesIsAReducedModelsChoiceNamedWhenWrong) {
  const std::string reduced =
      Replace(Minimal(), R"("type": "mass-spring", "structural_stiffness": 50)",
              R"("type": "reduced", "fem_cells": 12)");
  const auto with = [&](const std::string& volume, const std::string& base) {
    return Replace(base, R"("error_budget")",
                   R"("tissue": {"volume": )" + volume + R"(}, "error_budget")");
  };
  auto plain = ParseScene(reduced, "x.json");
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_FALSE(plain->volume_at_vertices);
  auto vertices = ParseScene(with(R"("vertices")", reduced), "x.json");
  ASSERT_TRUE(vertices.ok()) << vertices.error().message;
  EXPECT_TRUE(vertices->volume_at_vertices);
  EXPECT_TRUE(SceneMaterial(*vertices).nodal_volume);
  EXPECT_NE(Field(with(R"("nodes")", reduced)).find("tissue.volume: must be"), std::string::npos);
  EXPECT_NE(Field(with("1", reduced)).find("tissue.volume"), std::string::npos);
  EXPECT_NE(Field(with(R"("vertices")", Minimal()))
                .find("tissue.volume: \"vertices\" is for a "
                      "reduced model"),
            std::string::npos);
}

// A contact table's rotation correction is on unless the scene leaves it out; anything but a
// boolean, or the key on another mode, is refused by name.
TEST(SceneTest, TheContactTablesRotationCorrectionIsAChoiceNamedWhenWrong) {
  const std::string reduced =
      Replace(Minimal(), R"("type": "mass-spring", "structural_stiffness": 50)",
              R"("type": "reduced", "fem_cells": 12)");
  auto plain = ParseScene(reduced, "x.json");
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_TRUE(plain->region.reduced.rotation);
  auto straight = ParseScene(
      Replace(reduced, R"("fem_cells": 12)", R"("fem_cells": 12, "rotation": false)"), "x.json");
  ASSERT_TRUE(straight.ok()) << straight.error().message;
  EXPECT_FALSE(straight->region.reduced.rotation);
  EXPECT_NE(Field(Replace(reduced, R"("fem_cells": 12)", R"("fem_cells": 12, "rotation": 0)"))
                .find("rotation: must be true or false"),
            std::string::npos);
  EXPECT_NE(Field(Replace(reduced, R"("fem_cells": 12)",
                          R"("fem_cells": 12, "mode": "surface-twist", "rotation": false)"))
                .find("rotation: is the contact table's correction"),
            std::string::npos);
}

TEST(SceneTest, TheTissuesLawIsAReducedTwistsChoiceNamedWhenWrong) {
  const std::string twist = R"({"name": "t", "mesh": {"type": "limb", "preset": "forearm"},
    "regions": [{"name": "r", "model": {"type": "reduced", "mode": "twist", "levels": 4}}],
    "task": {"type": "twist", "target_deg": 45, "tolerance_deg": 5},
    "error_budget": {"rms": 0.05}})";
  const auto with = [](const std::string& tissue, const std::string& base) {
    return Replace(base, R"("error_budget")", R"("tissue": {)" + tissue + R"(}, "error_budget")");
  };
  auto plain = ParseScene(twist, "x.json");
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_EQ(plain->law, Scene::Law::kLinear);
  EXPECT_EQ(plain->region.reduced.levels, 4);
  auto neo = ParseScene(with(R"("law": "neo-hookean")", twist), "x.json");
  ASSERT_TRUE(neo.ok()) << neo.error().message;
  EXPECT_EQ(neo->law, Scene::Law::kNeoHookean);
  auto expo = ParseScene(with(R"("law": "exponential", "stiffening": 5)", twist), "x.json");
  ASSERT_TRUE(expo.ok()) << expo.error().message;
  EXPECT_EQ(expo->law, Scene::Law::kExponential);
  EXPECT_EQ(expo->stiffening, 5);
  auto relaxing = ParseScene(
      with(R"("relaxation": [{"g": 0.3, "tau_s": 0.2}, {"g": 0.2, "tau_s": 5}])", twist), "x.json");
  ASSERT_TRUE(relaxing.ok()) << relaxing.error().message;
  ASSERT_EQ(relaxing->relaxation.size(), 2u);
  EXPECT_EQ(relaxing->relaxation[1].g, 0.2);
  EXPECT_EQ(relaxing->relaxation[1].tau, 5);
  const std::pair<std::string, const char*> bad[] = {
      {R"("law": "ogden")", "tissue.law: must be"},
      {R"("law": "exponential")", "tissue.stiffening: is required"},
      {R"("law": "exponential", "stiffening": 0)", "tissue.stiffening"},
      {R"("law": "exponential", "stiffening": -1)", "tissue.stiffening"},
      {R"("law": "neo-hookean", "stiffening": 2)", "tissue.stiffening: is the exponential law's"},
      {R"("stiffening": 2)", "tissue.stiffening: is the exponential law's"},
      {R"("law": 3)", "tissue.law"},
      {R"("relaxation": [])", "tissue.relaxation: must be"},
      {R"("relaxation": [{"g": 1.2, "tau_s": 1}])", "tissue.relaxation[0].g"},
      {R"("relaxation": [{"g": 0.2, "tau_s": 0}])", "tissue.relaxation[0].tau_s"},
      {R"("relaxation": [{"g": 0.2}])", "tissue.relaxation[0].tau_s"},
      {R"("relaxation": [{"g": 0.6, "tau_s": 1}, {"g": 0.5, "tau_s": 2}])",
       "tissue.relaxation: the terms' g sum to 1"},
      {R"("relaxation": [3])", "tissue.relaxation[0]: must be an object"}};
  for (const auto& [tissue, field] : bad)
    EXPECT_NE(Field(with(tissue, twist)).find(field), std::string::npos) << tissue;
  // Only the reduced twist region carries a hyperelastic law; a press scene says so.
  EXPECT_NE(Field(with(R"("law": "neo-hookean")", Minimal()))
                .find("tissue.law: \"neo-hookean\" is carried only by a reduced twist region"),
            std::string::npos);
  EXPECT_NE(Field(with(R"("relaxation": [{"g": 0.3, "tau_s": 1}])", Minimal()))
                .find("tissue.relaxation: is carried only by a reduced twist region"),
            std::string::npos);
  EXPECT_NE(Field(Replace(twist, R"("levels": 4)", R"("levels": 40)")).find("levels"),
            std::string::npos);
}

TEST(SceneTest, EveryFieldsTypeIsCheckedNamingIt) {
  EXPECT_NE(Field(Replace(Minimal(), R"("name": "t", )", R"("name": "t", "description": 5, )"))
                .find("x.json: description: must be a string"),
            std::string::npos);
  EXPECT_TRUE(
      ParseScene(Replace(Minimal(), R"("name": "t", )", R"("name": "t", "description": "", )"),
                 "x.json")
          .ok());
  // Each value of the wrong JSON type, at every path of two scenes (every leaf and every object
  // or array above one): one error naming the file, never a throw.
  std::ifstream arm_file(ScenesDirectory() + "/arm-torsion.json");
  std::set<std::string> paths;
  std::vector<nlohmann::json> bases = {nlohmann::json::parse(Minimal()),
                                       nlohmann::json::parse(arm_file)};
  for (const nlohmann::json& base : bases) {
    const nlohmann::json flat = base.flatten();
    for (const auto& [leaf, value] : flat.items()) {
      paths.insert(leaf);
      for (size_t slash = leaf.rfind('/'); slash != 0 && slash != std::string::npos;
           slash = leaf.rfind('/', slash - 1))
        paths.insert(leaf.substr(0, slash));
    }
  }
  for (const auto& wrong :
       {nlohmann::json(5), nlohmann::json("s"), nlohmann::json::array(), nlohmann::json::object(),
        nlohmann::json(nullptr), nlohmann::json(true)}) {
    for (const nlohmann::json& base : bases) {
      for (const std::string& key : paths) {
        const nlohmann::json::json_pointer at(key);
        if (!base.contains(at)) continue;
        nlohmann::json j = base;
        j[at] = wrong;
        Expected<Scene> parsed = InvalidArgument("", "");
        ASSERT_NO_THROW(parsed = ParseScene(j.dump(), "x.json")) << key << " = " << wrong.dump();
        if (!parsed.ok()) {
          EXPECT_NE(parsed.error().message.find("x.json: "), std::string::npos);
        }
      }
    }
  }
  EXPECT_GT(paths.size(), 30u);
}

// A limb of 4,096 segments × 8,192 rings passed validation and ended in std::bad_alloc.
TEST(SceneTest, ASceneMustFitTheSessionMemoryBudget) {
  std::ifstream arm_file(ScenesDirectory() + "/arm-torsion.json");
  nlohmann::json arm = nlohmann::json::parse(arm_file);
  arm["mesh"]["segments"] = 4096;
  arm["mesh"]["rings"] = 8192;
  auto big = ParseScene(arm.dump(), "big.json");
  ASSERT_FALSE(big.ok());
  EXPECT_EQ(big.error().code, ErrorCode::kResourceExhausted);
  EXPECT_EQ(big.error().field, "mesh");
  EXPECT_NE(big.error().message.find("33554434 surface vertices"), std::string::npos)
      << big.error().message;
  EXPECT_NE(big.error().message.find("budget of 512 MiB"), std::string::npos);
  // A mass-spring sphere at the largest particle count the reader accepts costs too much; a
  // coil limb of 256 × 256 fits.
  EXPECT_EQ(Field(Replace(Minimal(), R"("particles": 256)", R"("particles": 300000)"))
                .find("x.json: mesh: 262146 surface vertices with the mass-spring model"),
            0u);
  arm["mesh"]["segments"] = 256;
  arm["mesh"]["rings"] = 256;
  EXPECT_TRUE(ParseScene(arm.dump(), "ok.json").ok());
  EXPECT_LE(EstimatedSessionBytes(ModelKind::kCoil, 6182), size_t{16} << 20);
  // Every shipped scene is far inside the budget.
  for (const auto& entry : std::filesystem::directory_iterator(ScenesDirectory())) {
    if (entry.path().extension() != ".json") continue;  // (kidney.stl is a scene's mesh)
    auto scene = LoadScene(entry.path().string());
    EXPECT_TRUE(scene.ok()) << entry.path();
  }
}

}  // namespace
}  // namespace vsurg::sim
