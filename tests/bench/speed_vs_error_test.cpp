// The study's command contract, run in its --quick form (what CI exercises).
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "common/core/csv.h"
#include "tests/support/temp_dir.h"

namespace vsurg {
namespace {

namespace fs = std::filesystem;

std::string Read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(SpeedVsErrorTest, QuickRunWritesTheCsvThePlotsAndNamesAModelPerScene) {
  const test::TempDir dir("sve");
  const std::string cmd = std::string(VSURG_BENCH_BINARY) + " speed-vs-error --quick --out " +
                          dir.string() + " 2>/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string out;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
  const int status = pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << out;

  auto rows = csv::Parse(Read(dir / "speed-vs-error.csv"), "speed-vs-error.csv");
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  ASSERT_GT(rows->size(), 20u);
  const auto& header = (*rows)[0].fields;
  std::map<std::string, size_t> col;
  for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  for (const char* c :
       {"model", "scene", "setting", "time_per_update_us", "rms_error", "max_error"})
    ASSERT_TRUE(col.count(c)) << c;
  std::set<std::string> scenes, models;
  std::map<std::string, std::map<std::string, double>> rms;  // scene → model → best RMS
  for (size_t r = 1; r < rows->size(); ++r) {
    const auto& f = (*rows)[r].fields;
    scenes.insert(f[col["scene"]]);
    models.insert(f[col["model"]]);
    if (f[col["model"]] == "fem" || f[col["model"]].rfind("coil", 0) == 0) {
      ASSERT_FALSE(f[col["rms_error"]].empty()) << f[col["model"]] << " " << f[col["setting"]];
      const double row_rms = std::stod(f[col["rms_error"]]);
      EXPECT_GT(row_rms, 0.0);
      EXPECT_LT(row_rms, 1.0);
      EXPECT_LE(row_rms, std::stod(f[col["max_error"]]));
    }
    if (!f[col["rms_error"]].empty()) {
      double& best = rms[f[col["scene"]]][f[col["model"]]];
      const double v = std::stod(f[col["rms_error"]]);
      best = best == 0 ? v : std::min(best, v);
    }
  }
  EXPECT_EQ(scenes, (std::set<std::string>{"arm-ramp",
                                           "arm-haptic",
                                           "calf-ramp",
                                           "sphere-palpation",
                                           "kidney-palpation",
                                           "organ-twist",
                                           "lump-search",
                                           "pattern-cut",
                                           "arm neo-Hookean 45°",
                                           "arm neo-Hookean 90°",
                                           "arm exponential b = 5 45°",
                                           "arm exponential b = 5 90°",
                                           "ball neo-Hookean 0.2 N",
                                           "ball neo-Hookean 2 N",
                                           "ball exponential b = 5 0.2 N",
                                           "ball exponential b = 5 2 N",
                                           "organ twist neo-Hookean 30°",
                                           "organ twist neo-Hookean 60°",
                                           "organ twist exponential b = 5 30°",
                                           "organ twist exponential b = 5 60°"}));
  // The load axis: against a neo-Hookean forearm the linear twist field stays within the 5%
  // budget to 90° (its torque within 2%); against a stiffening one its torque falls behind as the
  // twist grows, past the budget at 90°, where the table of load levels is the FEM at its levels.
  EXPECT_LT(rms["arm neo-Hookean 90°"]["reduced"], 0.05);
  EXPECT_GT(rms["arm exponential b = 5 90°"]["reduced"], 0.1);
  EXPECT_GT(rms["arm exponential b = 5 90°"]["reduced"],
            1.5 * rms["arm exponential b = 5 45°"]["reduced"]);
  for (const char* scene : {"arm neo-Hookean 45°", "arm exponential b = 5 90°"})
    EXPECT_LT(rms[scene]["reduced-table"], 1e-4) << scene;
  // The ball: the linear law's own FEM on the reference's mesh is the neo-Hookean one at the
  // study's light press and parts from it as the press grows (the quick run's coarse meshes).
  EXPECT_LT(rms["ball neo-Hookean 0.2 N"]["fem"], 0.01);
  EXPECT_GT(rms["ball neo-Hookean 2 N"]["fem"], 4 * rms["ball neo-Hookean 0.2 N"]["fem"]);
  EXPECT_LT(rms["ball neo-Hookean 2 N"]["reduced"], 0.2);
  // The organ's forceps twist: the stiffening law's own light answer carried on linearly falls
  // behind as the twist grows, and a table of levels (the angles between two of them) holds it.
  EXPECT_GT(rms["organ twist exponential b = 5 60°"]["reduced"], 0.1);
  EXPECT_GT(rms["organ twist exponential b = 5 60°"]["reduced"],
            1.5 * rms["organ twist exponential b = 5 30°"]["reduced"]);
  for (const char* scene :
       {"organ twist neo-Hookean 30°", "organ twist neo-Hookean 60°",
        "organ twist exponential b = 5 30°", "organ twist exponential b = 5 60°"})
    EXPECT_LT(rms[scene]["reduced-table"], 0.05) << scene;
  for (const char* m :
       {"coil-paper", "coil-per-ring", "fem", "mass-spring", "ring-layer", "cut-membrane"})
    EXPECT_TRUE(models.count(m)) << m;
  // The per-ring calibration goes beyond the paper: closer to Saint-Venant on every limb scene.
  for (const char* scene : {"arm-ramp", "arm-haptic", "calf-ramp"})
    EXPECT_LT(rms[scene]["coil-per-ring"], rms[scene]["coil-paper"]) << scene;
  for (const char* png : {"speed-vs-error.png", "marker8.png"}) {
    const std::string bytes = Read(dir / png);
    ASSERT_GT(bytes.size(), 1000u) << png;
    EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << png;
  }
  EXPECT_NE(out.find("cheapest within it"), std::string::npos);
  // Every scene file appears against its own budget, run with its own parameters. Within it:
  // the coil arm with its per-coil rigidities (the paper's single rigidity was 32% against
  // 30%), the mass-spring sphere's and the ring layer's calibrated files (22% and 18–34%
  // before), the kidney's reduced table, the organ's surface twist (its coil was 34%).
  // Over it in a quick run: the reduced arm's 5% on the quick run's coarse FEM (level 2).
  std::map<std::string, std::string> verdict;  // file → its table line
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);)
    if (line.rfind("| `scenes/", 0) == 0) verdict[line.substr(10, line.find('`', 10) - 10)] = line;
  for (const auto& e : fs::directory_iterator(VSURG_SCENES_DIR)) {
    if (e.path().extension() != ".json") continue;  // (kidney.stl is a scene's mesh)
    EXPECT_TRUE(verdict.count(e.path().filename().string())) << e.path();
  }
  for (const char* file : {"arm-torsion.json", "sphere-palpation-256.json", "kidney-palpation.json",
                           "calf-torsion.json", "sphere-palpation-rings.json",
                           "organ-surface-twist.json", "lump-search.json", "pattern-cut.json"}) {
    EXPECT_NE(verdict[file].find("| within |"), std::string::npos) << verdict[file];
  }
  EXPECT_NE(verdict["arm-torsion.json"].find("coil-scene, scene parameters"), std::string::npos);
  EXPECT_NE(verdict["sphere-palpation-256.json"].find("mass-spring-scene"), std::string::npos);
  EXPECT_NE(verdict["arm-torsion-reduced.json"].find("**over its budget**"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "BENCHMARKS.md"));  // only written for docs/ or --benchmarks
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vsurg
