// vsurg-bench's commands that bench/peers sets against the peers: the round trip on real sockets
// on loopback, the floor (udp-floor, a plain echo) and ours (haptic-rtt, the UDP endpoint with a
// simulation per station), with the same stations, pacing and JSON (bench/peers/rtt.sh); and
// the FEM step with the bar it writes out for VegaFEM (fem-step, bench/peers/fem.sh).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/processes.h"
#include "tests/support/temp_dir.h"

namespace vsurg {
namespace {

nlohmann::json RunBench(const std::string& args) {
  const test::ShellRun r = test::Shell(std::string(VSURG_BENCH_BINARY) + " " + args);
  EXPECT_EQ(r.code, 0) << args << "\n" << r.out;
  return r.code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json::object();
}

TEST(RttCommandsTest, TheFloorAndOursAnswerEveryStationWithTheSameStatistics) {
  for (const std::string command : {"udp-floor", "haptic-rtt"}) {
    const nlohmann::json j = RunBench(command + " --stations 4 --seconds 0.5 --json");
    ASSERT_TRUE(j.contains("sent")) << command;
    SCOPED_TRACE(command + ": " + j.dump());
    EXPECT_EQ(j["stations"], 4);
    // 4 stations at 1 kHz for 0.5 s: the window holds the datagrams scheduled in it, however
    // late a loaded machine sends them (or skips them, when more than 20 ms behind).
    EXPECT_GT(j["sent"].get<int>(), 1000);
    EXPECT_LE(j["sent"].get<int>(), 2000);
    // Every answer is opened and decoded (a broken echo or codec gives none); the last few may
    // still be in flight when the run ends on a loaded machine.
    EXPECT_GT(j["received"].get<double>(), 0.9 * j["sent"].get<double>());
    EXPECT_LE(j["received"].get<int>(), j["sent"].get<int>());
    const double p50 = j["rtt_p50_us"], p99 = j["rtt_p99_us"], p999 = j["rtt_p999_us"];
    EXPECT_GT(p50, 0.0);
    EXPECT_LE(p50, p99);
    EXPECT_LE(p99, p999);
    // At the answer's arrival (the kernel's stamp at the station's socket): each answer arrives
    // before the driver has read and decoded it, so every quantile is lower, strictly (a run
    // without the stamps would give the same), and still positive (the time it sat at the
    // station, taken off, is on the stamp's own clock).
    const double a50 = j["arrival_rtt_p50_us"], a99 = j["arrival_rtt_p99_us"],
                 a999 = j["arrival_rtt_p999_us"];
    EXPECT_GT(a50, 0.0);
    EXPECT_LT(a50, p50);
    EXPECT_LT(a99, p99);
    EXPECT_LT(a999, p999);
    // The driver's own load: its one thread's busy share of a core, and its late slots.
    EXPECT_GT(j["driver_busy_cores"].get<double>(), 0.0);
    EXPECT_LT(j["driver_busy_cores"].get<double>(), 1.1);
    EXPECT_GE(j["driver_late_slots"].get<double>(), 0.0);
    EXPECT_LE(j["driver_late_slots"].get<double>(), 1.0);
    EXPECT_GE(j["driver_max_late_us"].get<double>(), 0.0);
  }
  EXPECT_EQ(RunBench("udp-floor --stations 1 --seconds 0.2 --json")["server"], "udp-echo");
}

TEST(RttCommandsTest, BadArgumentsAreRefusedWithTheirName) {
  for (const std::string bad : {"--stations 0", "--stations 2000", "--seconds -1", "--bogus 1",
                                "--realtime-priority 120"}) {
    const test::ShellRun r =
        test::Shell(std::string(VSURG_BENCH_BINARY) + " udp-floor " + bad + " 2>&1");
    EXPECT_EQ(r.code, 2) << bad;
    EXPECT_NE(r.out.find(bad.substr(0, bad.find(' '))), std::string::npos) << r.out;
  }
}

TEST(FemStepCommandTest, StepsTheBarAndATighterToleranceTakesMoreIterations) {
  const nlohmann::json loose = RunBench("fem-step --rings 2 --steps 3 --json");
  const nlohmann::json tight = RunBench("fem-step --rings 2 --steps 3 --tolerance 1e-6 --json");
  ASSERT_TRUE(loose.contains("tets") && tight.contains("tets"));
  EXPECT_GT(loose["tets"].get<int>(), 100);
  EXPECT_GT(loose["ms_median"].get<double>(), 0.0);
  EXPECT_GE(loose["ms_median"].get<double>(), loose["ms_min"].get<double>());
  EXPECT_GT(loose["cg_iterations"].get<double>(), 0.0);
  EXPECT_GT(tight["cg_iterations"].get<double>(), loose["cg_iterations"].get<double>());
  // 23 steps of 1 ms under 2 mN·m: the tip has started to turn, by well under a centimetre.
  const double moved = loose["max_displacement_m"];
  EXPECT_GT(moved, 1e-6);
  EXPECT_LT(moved, 1e-2);
  EXPECT_NEAR(tight["max_displacement_m"].get<double>(), moved, 0.02 * moved);
}

// What VegaFEM reads is the bar we step: its vertex and element counts, a fixed base, and tip
// forces that add up to the 2 mN·m torque about the bar's axis and no net force.
TEST(FemStepCommandTest, ExportWritesTheBarItsBaseAndAPureTorque) {
  const test::TempDir tmp("fem_export");
  const std::string dir = (tmp / "out").string();
  const test::ShellRun r =
      test::Shell(std::string(VSURG_BENCH_BINARY) + " fem-step --rings 2 --export " + dir);
  ASSERT_EQ(r.code, 0) << r.out;
  const int tets = RunBench("fem-step --rings 2 --steps 1 --json")["tets"];
  std::ifstream veg(dir + "/mesh.veg");
  std::string line;
  std::vector<Eigen::Vector3d> x;
  int elements = -1;
  while (std::getline(veg, line)) {
    if (line == "*VERTICES") {
      int n = 0;
      veg >> n;
      std::getline(veg, line);
      for (int i = 0; i < n; ++i) {
        int index;
        Eigen::Vector3d p;
        veg >> index >> p.x() >> p.y() >> p.z();
        EXPECT_EQ(index, i + 1);
        x.push_back(p);
      }
    }
    if (line == "TET") veg >> elements;
  }
  EXPECT_GT(x.size(), 100u);
  EXPECT_EQ(elements, tets);
  std::ifstream fixed(dir + "/fixed.txt");
  int v, fixed_count = 0;
  while (fixed >> v) {
    ASSERT_LT(v, static_cast<int>(x.size()));
    EXPECT_NEAR(x[v].z(), 0.0, 1e-12);  // the base
    ++fixed_count;
  }
  EXPECT_GT(fixed_count, 3);
  std::ifstream forces(dir + "/forces.txt");
  Eigen::Vector3d total = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  Eigen::Vector3d f;
  while (forces >> v >> f.x() >> f.y() >> f.z()) {
    ASSERT_LT(v, static_cast<int>(x.size()));
    total += f;
    torque += x[v].cross(f);
  }
  EXPECT_LT(total.norm(), 1e-9);
  EXPECT_NEAR(torque.z(), 2e-3, 1e-9);
  EXPECT_LT(torque.head<2>().norm(), 1e-9);
  std::filesystem::remove_all(dir);
}

TEST(FemStepCommandTest, BadArgumentsAreRefusedWithTheirName) {
  for (const std::string bad : {"--rings 0", "--steps 0", "--tolerance 2", "--bogus 1"}) {
    const test::ShellRun r =
        test::Shell(std::string(VSURG_BENCH_BINARY) + " fem-step " + bad + " 2>&1");
    EXPECT_EQ(r.code, 2) << bad;
    EXPECT_NE(r.out.find(bad.substr(0, bad.find(' '))), std::string::npos) << r.out;
  }
}

// The neo-Hookean step with inertia on the same bar under 20 mN·m: every step converges, a tighter
// Newton tolerance takes at least as many iterations and moves the bar alike, and what VegaFEM
// reads (bench/peers/hyper.sh) is that bar, that torque and no damping.
TEST(HyperStepCommandTest, StepsTheBarAndExportsItUndamped) {
  const nlohmann::json loose = RunBench("hyper-step --rings 2 --steps 3 --json");
  const nlohmann::json tight = RunBench("hyper-step --rings 2 --steps 3 --tolerance 1e-9 --json");
  ASSERT_TRUE(loose.contains("converged") && tight.contains("converged"));
  EXPECT_TRUE(loose["converged"].get<bool>());
  EXPECT_TRUE(tight["converged"].get<bool>());
  EXPECT_GE(loose["newton_iterations"].get<double>(), 1.0);
  EXPECT_GE(tight["newton_iterations"].get<double>(), loose["newton_iterations"].get<double>());
  const double moved = loose["max_displacement_m"];
  EXPECT_GT(moved, 1e-4);  // 23 ms under ten times fem-step's torque: millimetres
  EXPECT_LT(moved, 2e-2);
  EXPECT_NEAR(tight["max_displacement_m"].get<double>(), moved, 1e-3 * moved);
  const test::TempDir tmp("hyper_export");
  const std::string dir = (tmp / "out").string();
  ASSERT_EQ(
      test::Shell(std::string(VSURG_BENCH_BINARY) + " hyper-step --rings 2 --export " + dir).code,
      0);
  std::ifstream settings(dir + "/settings.txt");
  std::map<std::string, double> values;
  std::string key;
  double value;
  while (settings >> key >> value) values[key] = value;
  EXPECT_EQ(values["dt"], 1e-3);
  EXPECT_EQ(values["mass_damping"], 0.0);
  EXPECT_EQ(values["stiffness_damping"], 0.0);
  std::ifstream veg(dir + "/mesh.veg"), forces(dir + "/forces.txt");
  std::string line;
  std::vector<Eigen::Vector3d> x;
  while (std::getline(veg, line) && line != "*VERTICES") {
  }
  int n = 0, index;
  veg >> n;
  std::getline(veg, line);  // the rest of the count's line
  for (Eigen::Vector3d p;
       static_cast<int>(x.size()) < n && veg >> index >> p.x() >> p.y() >> p.z();)
    x.push_back(p);
  ASSERT_EQ(static_cast<int>(x.size()), n);
  Eigen::Vector3d torque = Eigen::Vector3d::Zero(), f;
  while (forces >> index >> f.x() >> f.y() >> f.z()) torque += x[index].cross(f);
  EXPECT_NEAR(torque.z(), 20e-3, 1e-9);
  for (const std::string bad : {"--rings 0", "--steps 0", "--tolerance 2", "--bogus 1"}) {
    const test::ShellRun r =
        test::Shell(std::string(VSURG_BENCH_BINARY) + " hyper-step " + bad + " 2>&1");
    EXPECT_EQ(r.code, 2) << bad;
    EXPECT_NE(r.out.find(bad.substr(0, bad.find(' '))), std::string::npos) << r.out;
  }
}

}  // namespace
}  // namespace vsurg
