#include "common/cli/vsurg_sim.h"

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/geometry/mesh_generators.h"
#include "common/geometry/obj_io.h"
#include "common/sim/scene.h"
#include "tests/support/deadline.h"
#include "tests/support/temp_dir.h"

namespace vsurg::cli {
namespace {

using json = nlohmann::json;

struct SimRun {
  int code;
  std::string out, err;
};

SimRun Sim(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const int code = RunVsurgSim(args, out, err);
  return {code, out.str(), err.str()};
}

const std::vector<std::string> kArm = {"--core-radius", "0.02",    "--thickness", "0.01",
                                       "--width",       "0.06",    "--coils",     "23",
                                       "--modulus",     "4.253e8", "--max-force", "0.163"};

std::vector<std::string> With(std::vector<std::string> head, const std::vector<std::string>& tail) {
  head.insert(head.end(), tail.begin(), tail.end());
  return head;
}

int Lines(const std::string& s) {
  return static_cast<int>(std::count(s.begin(), s.end(), '\n'));
}

TEST(VsurgSimTest, CoilJsonHasTheContractKeysConsistentWithEachOther) {
  const SimRun r = Sim(With({"coil", "--torque", "2.07", "--json"}, kArm));
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  for (const char* key : {"P", "overload", "coil_torques", "twist_turns", "twist_angles",
                          "total_twist_rad", "boundary_angles"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  const int p = j["P"];
  EXPECT_EQ(p, 18);
  EXPECT_FALSE(j["overload"].get<bool>());
  ASSERT_EQ(j["coil_torques"].size(), static_cast<size_t>(p));
  ASSERT_EQ(j["boundary_angles"].size(), static_cast<size_t>(p + 1));
  double torque = 0, twist = 0;
  for (int i = 0; i < p; ++i) {
    torque += j["coil_torques"][i].get<double>();
    twist += j["twist_angles"][i].get<double>();
  }
  EXPECT_NEAR(torque, 2.07, 1e-12);
  EXPECT_NEAR(twist, j["total_twist_rad"].get<double>(), 1e-12);
  EXPECT_EQ(j["boundary_angles"][0].get<double>(), j["total_twist_rad"].get<double>());
  EXPECT_EQ(j["boundary_angles"][p].get<double>(), 0.0);
}

TEST(VsurgSimTest, CoilInverseUndoesCoil) {
  const json fwd = json::parse(Sim(With({"coil", "--torque", "-1.5", "--json"}, kArm)).out);
  const double twist = fwd["total_twist_rad"];
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", twist);
  const SimRun r = Sim(With({"coil-inverse", "--twist", buf, "--json"}, kArm));
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_NEAR(j["torque"].get<double>(), -1.5, 1e-12);
  EXPECT_GT(j["stiffness"].get<double>(), 0);
  EXPECT_EQ(j["P"], fwd["P"]);
  EXPECT_FALSE(j["overload"].get<bool>());
  const json over = json::parse(Sim(With({"coil-inverse", "--twist", "100", "--json"}, kArm)).out);
  EXPECT_TRUE(over["overload"].get<bool>());
  EXPECT_EQ(over["stiffness"].get<double>(), 0.0);
}

TEST(VsurgSimTest, FrictionDefaultsToThePapersValue) {
  const json a = json::parse(Sim(With({"coil", "--torque", "1", "--json"}, kArm)).out);
  const json b =
      json::parse(Sim(With({"coil", "--torque", "1", "--json", "--friction", "1.25"}, kArm)).out);
  const json c =
      json::parse(Sim(With({"coil", "--torque", "1", "--json", "--friction=2.5"}, kArm)).out);
  EXPECT_EQ(a["total_twist_rad"], b["total_twist_rad"]);
  EXPECT_NEAR(c["total_twist_rad"].get<double>(), 2 * a["total_twist_rad"].get<double>(), 1e-12);
}

TEST(VsurgSimTest, BadArgumentsExitTwoWithOneLineNamingTheArgument) {
  struct Case {
    std::vector<std::string> args;
    std::string expect;  // must appear in the one stderr line
  };
  const Case cases[] = {
      {With({"coil", "--torque", "1"}, {"--thickness", "0.01"}), "--core-radius"},
      {With({"coil", "--torque", "abc"}, kArm), "--torque: 'abc' is not a finite number"},
      {With({"coil", "--torque", "nan"}, kArm), "--torque"},
      {With({"coil", "--torque", "1", "--bogus", "2"}, kArm), "--bogus: unknown option"},
      {With({"coil", "--torque", "1", "--torque", "2"}, kArm), "--torque: given more than once"},
      {With({"coil", "--torque", "1", "stray"}, kArm), "unexpected argument 'stray'"},
      {With({"coil", "--torque"}, {}), "--torque: needs a value"},
      {{"coil", "--torque", "1", "--core-radius", "0.02", "--thickness", "-0.01", "--width", "0.06",
        "--coils", "23", "--modulus", "4e8", "--max-force", "0.16"},
       "--thickness: coil thickness h (m) must be finite and > 0"},
      {{"coil", "--torque", "1", "--core-radius", "0.02", "--thickness", "0.01", "--width", "0.06",
        "--coils", "0", "--modulus", "4e8", "--max-force", "0.16"},
       "--coils"},
      {{"coil", "--torque", "1", "--core-radius", "0.02", "--thickness", "0.01", "--width", "0.06",
        "--coils", "2.5", "--modulus", "4e8", "--max-force", "0.16"},
       "--coils: '2.5' is not an integer"},
      {With({"coil-inverse", "--twist", "1"}, {"--core-radius", "0.02"}), "--thickness"},
      {{"deform", "--scene", "spleen", "--out", "x.obj"}, "--scene: unknown scene 'spleen'"},
      {{"deform", "--scene", "arm"}, "--out: is required"},
      {{"deform", "--out", "x.obj", "--steps", "0"}, "--steps"},
      {{"calibrate", "--shear-modulus", "-5"}, "--shear-modulus"},
      {{"calibrate", "--torques", "0"}, "--torques"},
      {{"frobnicate"}, "unknown command 'frobnicate'"},
      {{}, "a command is required"},
  };
  for (const Case& c : cases) {
    const SimRun r = Sim(c.args);
    EXPECT_EQ(r.code, 2) << c.expect;
    EXPECT_EQ(Lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << "stderr: " << r.err;
    EXPECT_TRUE(r.out.empty());
  }
}

TEST(VsurgSimTest, EveryCommandHasHelp) {
  for (const char* cmd :
       {"coil", "coil-inverse", "deform", "calibrate", "msm", "run", "trainee", "score"}) {
    const SimRun r = Sim({cmd, "--help"});
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find(std::string("usage: vsurg-sim ") + cmd), std::string::npos);
    EXPECT_TRUE(r.err.empty());
  }
  const SimRun top = Sim({"--help"});
  EXPECT_EQ(top.code, 0);
  EXPECT_NE(top.out.find("coil-inverse"), std::string::npos);
}

std::string WriteTemp(const std::filesystem::path& file, const std::string& text) {
  std::ofstream(file) << text;
  return file.string();
}

TEST(VsurgSimTest, ScoreReportsTheWeightedMeansAndReliability) {
  const test::TempDir tmp("cli");
  const std::string path = WriteTemp(tmp / "ratings.csv",
                                     "evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9\n"
                                     "a1,intern,6,6,6,6,6,6,6,6,6\n"
                                     "b1,associate_chief,7,7,7,7,7,7,7,7,8\n"
                                     "c1,chief,8,8,8,8,8,8,8,8,9\n"
                                     "c2,chief,10,10,10,10,10,10,10,10,10\n");
  const SimRun r = Sim({"score", "--input", path, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  for (const char* key : {"index_means", "index_variances", "comprehensive", "icc2k",
                          "cronbach_alpha", "weights", "raters_per_group"})
    EXPECT_TRUE(j.contains(key)) << key;
  // i1: 0.2·6 + 0.3·7 + 0.5·mean(8, 10)
  const double m1 = 0.2 * 6 + 0.3 * 7 + 0.5 * 9;
  EXPECT_NEAR(j["index_means"][0].get<double>(), m1, 1e-12);
  const double s1 =
      ((6 - m1) * (6 - m1) + (7 - m1) * (7 - m1) + (8 - m1) * (8 - m1) + (10 - m1) * (10 - m1)) / 4;
  EXPECT_NEAR(j["index_variances"][0].get<double>(), s1, 1e-12);
  EXPECT_EQ(j["index_means"].size(), 9u);
  EXPECT_GT(j["cronbach_alpha"].get<double>(), 0.9);  // the raters rank the indexes alike

  const std::string bad = WriteTemp(tmp / "ratings_bad.csv", "a1,intern,6,6,6,6,6,6,6,6,12\n");
  const SimRun b = Sim({"score", "--input", bad, "--json"});
  EXPECT_EQ(b.code, 2);
  EXPECT_EQ(Lines(b.err), 1);
  EXPECT_NE(b.err.find("i9"), std::string::npos) << b.err;
  EXPECT_TRUE(b.out.empty());
  const std::string weights =
      WriteTemp(tmp / "weights.json",
                R"({"name":"x","group":{"intern":0.5,"associate_chief":0.5,"chief":0.5},)"
                R"("index":[0.15,0.15,0.15,0.15,0.1,0.1,0.1,0.05,0.05]})");
  const SimRun w = Sim({"score", "--input", path, "--weights", weights});
  EXPECT_EQ(w.code, 2);
  EXPECT_NE(w.err.find("group_weights"), std::string::npos) << w.err;
}

TEST(VsurgSimTest, DeformWritesTheTwistedArmAndReportsEachStep) {
  const test::TempDir tmp("cli");
  const std::string path = (tmp / "arm.obj").string();
  const SimRun r = Sim(
      {"deform", "--scene", "arm", "--torque", "2.07", "--steps", "4", "--out", path, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  ASSERT_EQ(j["steps"].size(), 4u);
  int prev_p = 0;
  double prev_twist = 0;
  for (const json& s : j["steps"]) {
    EXPECT_GE(s["P"].get<int>(), prev_p);
    EXPECT_GT(s["total_twist_rad"].get<double>(), prev_twist);
    EXPECT_FALSE(s["overload"].get<bool>());
    EXPECT_GT(s["moved_vertices"].get<int>(), 0);
    prev_p = s["P"];
    prev_twist = s["total_twist_rad"];
  }
  auto mesh = geometry::ReadObj(path);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  auto rest = geometry::MakeLimb(geometry::ForearmPreset());
  ASSERT_EQ(mesh->VertexCount(), rest->surface.VertexCount());
  EXPECT_EQ(mesh->triangles, rest->surface.triangles);
  // The wrist ring turned by the reported twist; the elbow ring did not move.
  const double twist = j["steps"][3]["total_twist_rad"];
  const int n = rest->params.segments_around, last = (rest->params.rings_along - 1) * n;
  const geometry::Vec3 w0 = rest->surface.positions[last], w1 = mesh->positions[last];
  EXPECT_NEAR(std::atan2(w1.y(), w1.x()) - std::atan2(w0.y(), w0.x()), twist, 1e-6);
  EXPECT_NEAR((mesh->positions[0] - rest->surface.positions[0]).norm(), 0, 1e-9);
}

TEST(VsurgSimTest, DeformToAnUnwritablePathFailsWithExitOne) {
  const SimRun r = Sim({"deform", "--out", "/nonexistent/dir/arm.obj"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--out"), std::string::npos);
}

TEST(VsurgSimTest, CalibrateReportsBothFits) {
  const SimRun r = Sim({"calibrate", "--scene", "arm", "--max-torque", "0.1", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  const double paper = j["two_parameter"]["profile_rms"], ring = j["per_ring"]["profile_rms"];
  EXPECT_GT(paper, 0.1);
  EXPECT_LT(ring, paper);
  EXPECT_EQ(j["per_ring"]["coil_rigidity"].size(), 23u);
  // At a single operating torque the per-ring model is a close reduced-order model.
  const json one =
      json::parse(Sim({"calibrate", "--max-torque", "0.1", "--torques", "1", "--json"}).out);
  EXPECT_EQ(one["reference"]["torques"], 1);
  EXPECT_LT(one["per_ring"]["profile_rms"].get<double>(),
            0.2 * one["two_parameter"]["profile_rms"].get<double>());
  // The per-ring fit with the scene's F_t held keeps the arm's 3.3 N·m capacity (what
  // scenes/arm-torsion.json carries) and still beats the paper's two parameters over a ramp.
  const json full =
      json::parse(Sim({"calibrate", "--scene", "arm", "--shear-modulus", "224702", "--json"}).out);
  const json& held = full["per_ring_at_capacity"];
  EXPECT_NEAR(held["capacity"].get<double>(), 3.30, 1e-9);
  EXPECT_EQ(held["coil_rigidity"].size(), 23u);
  EXPECT_LT(held["profile_rms"].get<double>(),
            0.8 * full["two_parameter"]["profile_rms"].get<double>());
}

TEST(VsurgSimTest, MsmPressesTheSphereWithEveryIntegrator) {
  double force_midpoint = 0;
  for (const char* integrator :
       {"explicit-euler", "symplectic-euler", "midpoint", "rk4", "verlet", "implicit-euler"}) {
    const SimRun r =
        Sim({"msm", "--mesh", "sphere", "--particles", "256", "--integrator", integrator, "--dt",
             "0.001", "--steps", "600", "--press", "0.005", "--json"});
    ASSERT_EQ(r.code, 0) << r.err;
    const json j = json::parse(r.out);
    for (const char* key : {"kinetic_energy", "potential_energy", "max_displacement",
                            "contact_force", "steps_per_second", "diverged"}) {
      EXPECT_TRUE(j.contains(key)) << key;
    }
    EXPECT_FALSE(j["diverged"].get<bool>()) << integrator;
    EXPECT_EQ(j["particles"], 258);
    EXPECT_NEAR(j["max_displacement"].get<double>(), 0.005, 1e-3) << integrator;
    EXPECT_GT(j["potential_energy"].get<double>(), 0);
    EXPECT_GT(j["contact_force"].get<double>(), 0) << integrator;  // the tissue pushes back
    EXPECT_GT(j["steps_per_second"].get<double>(), 0);
    if (std::string(integrator) == "midpoint") force_midpoint = j["contact_force"];
    if (std::string(integrator) == "rk4") {
      // Two second-order-or-better methods agree on the pressed state.
      EXPECT_NEAR(j["contact_force"].get<double>(), force_midpoint, 0.02 * force_midpoint);
    }
  }
}

TEST(VsurgSimTest, MsmReportsDivergenceInsteadOfNan) {
  const SimRun r = Sim({"msm", "--integrator", "explicit-euler", "--dt", "0.01", "--stiffness",
                        "5000", "--steps", "200", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_TRUE(j["diverged"].get<bool>());
  EXPECT_LT(j["steps"].get<int>(), 200);
  EXPECT_TRUE(std::isfinite(j["kinetic_energy"].get<double>()));
}

TEST(VsurgSimTest, MsmBadArgumentsExitTwo) {
  for (const auto& [args, expect] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"msm", "--integrator", "leapfrog"}, "--integrator: unknown integrator 'leapfrog'"},
           {{"msm", "--dt", "0"}, "--dt"},
           {{"msm", "--steps", "-1"}, "--steps"},
           {{"msm", "--mesh", "/nonexistent/x.obj"}, "--mesh: /nonexistent/x.obj: no such file"},
           {{"msm", "--stiffness", "-5"}, "--stiffness"},
           {{"msm", "--volume", "solid"}, "--volume"}}) {
    const SimRun r = Sim(args);
    EXPECT_EQ(r.code, 2) << expect;
    EXPECT_EQ(Lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(expect), std::string::npos) << r.err;
  }
}

TEST(VsurgSimTest, TraineeAndRunReplayAScene) {
  const test::TempDir tmp("cli");
  const std::string path = (tmp / "twist.csv").string();
  SimRun r = Sim({"trainee", "--scene", "arm-torsion", "--style", "good", "--out", path});
  ASSERT_EQ(r.code, 0) << r.err;
  r = Sim({"run", "--scene", "arm-torsion", "--trajectory", path, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["scene"], "arm-torsion");
  EXPECT_GT(j["samples"].get<int>(), 5000);
  const double peak = j["peak_force"];
  EXPECT_GT(peak, 1.0);
  EXPECT_LE(peak, 3.3 + 1e-9);  // newtons, after the Touch-class limit
  const json& m = j["metrics"];
  for (const char* key :
       {"completed", "completion_time", "task_error", "peak_force", "time_over_force_limit",
        "path_length", "rms_jerk", "overload_events", "score"}) {
    EXPECT_TRUE(m.contains(key)) << key;
  }
  EXPECT_TRUE(m["completed"].get<bool>());
  EXPECT_GE(m["score"].get<double>(), 8.0);
  EXPECT_EQ(j["grasps"], 1);
}

TEST(VsurgSimTest, RunRejectsBadTrajectoriesAndScenes) {
  const test::TempDir tmp("cli");
  const std::string path = (tmp / "bad.csv").string();
  {
    std::ofstream f(path);
    f << "t,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0.1,1,0,0,0,0\n0.001,0,zero,0.1,1,0,0,0,0\n";
  }
  SimRun r = Sim({"run", "--scene", "arm-torsion", "--trajectory", path});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find(path + ":3: column y: 'zero' is not a number"), std::string::npos) << r.err;
  {
    std::ofstream f(path);
    f << "time,x,y,z\n";
  }
  r = Sim({"run", "--scene", "arm-torsion", "--trajectory", path});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("the header must be"), std::string::npos) << r.err;
  r = Sim({"run", "--scene", "no-such-scene", "--trajectory", path});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--scene: no scene 'no-such-scene'"), std::string::npos) << r.err;
  r = Sim({"trainee", "--scene", "arm-torsion", "--style", "lazy", "--out", path});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--style"), std::string::npos);
}

// A two-row trajectory (0 s, then 1e308 s) hung `vsurg-sim run` in the trial recorder's grid walk;
// a time jump in a mass-spring replay did too; a scene whose description was a number gave
// "internal error" and exit 1.
TEST(VsurgSimTest, RunSurvivesClockJumpsAndBadSceneFieldTypes) {
  const test::TempDir dir("cli");
  const std::string path = (dir / "jump.csv").string();
  {
    std::ofstream f(path);
    f << "t,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0.3,1,0,0,0,0\n1e308,0,0,0.3,1,0,0,0,0\n"
         "1e7,0,0,0.06,1,0,0,0,0\n1.0000001e7,0,0,0.045,1,0,0,0,0\n";
  }
  for (const char* scene : {"arm-torsion", "sphere-palpation-256"}) {
    SimRun r;
    test::ReturnsWithin(60, "vsurg-sim run", [&] {
      r = Sim({"run", "--scene", scene, "--trajectory", path, "--json"});
    });
    EXPECT_EQ(r.code, 0) << scene << ": " << r.err;
    const json j = json::parse(r.out);
    EXPECT_LE(j["metrics"]["duration"].get<double>(), 3.0) << scene;
  }
  const std::string bad = (dir / "vsurg_cli_bad_scene.json").string();
  {
    std::ifstream in(sim::ScenesDirectory() + "/arm-torsion.json");
    json j = json::parse(in);
    j["description"] = 3;
    std::ofstream(bad) << j.dump();
  }
  const SimRun r = Sim({"run", "--scene", bad, "--trajectory", path});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(Lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("description: must be a string"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
}

// The real binary, as other tools call it: exit status and streams.
int RunBinary(const std::string& args, std::string& out, std::string& err) {
  const test::TempDir dir("cli_streams");
  const std::string o = (dir / "out.txt").string(), e = (dir / "err.txt").string();
  const int status =
      std::system((std::string(VSURG_SIM_BINARY) + " " + args + " >" + o + " 2>" + e).c_str());
  auto slurp = [](const std::string& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  out = slurp(o);
  err = slurp(e);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(VsurgSimBinaryTest, ExitCodesAndStreams) {
  std::string out, err;
  EXPECT_EQ(
      RunBinary("coil --torque 2.07 --core-radius 0.02 --thickness 0.01 --width 0.06 --coils 23 "
                "--modulus 4.253e8 --max-force 0.163 --json",
                out, err),
      0);
  EXPECT_EQ(json::parse(out)["P"], 18);
  EXPECT_EQ(RunBinary("coil --torque 1 --core-radius 0 --thickness 0.01 --width 0.06 --coils 23 "
                      "--modulus 4e8 --max-force 0.1",
                      out, err),
            2);
  EXPECT_EQ(Lines(err), 1);
  EXPECT_NE(err.find("--core-radius"), std::string::npos);
  EXPECT_EQ(RunBinary("deform --help", out, err), 0);
  EXPECT_NE(out.find("--scene"), std::string::npos);
}

}  // namespace
}  // namespace vsurg::cli

namespace vsurg::cli {
namespace {

// vsurg-sim cut: the straight drill by the expert hand, its JSON's figures consistent with each
// other; a bad hand and a missing drill refused by name.
TEST(VsurgSimCutTest, TheStraightDrillRunsAndBadArgumentsAreRefused) {
  const std::string drill = sim::ScenesDirectory() + "/drills/straight-cut.json";
  const SimRun r = Sim({"cut", "--drill", drill, "--hand", "expert"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["drill"], "straight-cut");
  EXPECT_TRUE(j["completed"].get<bool>());
  EXPECT_NEAR(j["cutting_force_n"].get<double>(), 1700 * 1.2e-3, 1e-9);
  EXPECT_LT(j["force_rms_error"].get<double>(), 0.1);
  EXPECT_LE(j["deviation_rms_mm"].get<double>(), j["deviation_max_mm"].get<double>());
  EXPECT_GT(j["cut_edges"].get<int>(), 10);
  EXPECT_GE(j["tissue_step"]["p99_us"].get<double>(), j["tissue_step"]["p50_us"].get<double>());
  const SimRun bad = Sim({"cut", "--drill", drill, "--hand", "surgeon"});
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.err.find("--hand"), std::string::npos) << bad.err;
  const SimRun missing = Sim({"cut", "--drill", "/nonexistent/drill.json"});
  EXPECT_NE(missing.code, 0);
  EXPECT_NE(missing.err.find("drill"), std::string::npos) << missing.err;
}

}  // namespace
}  // namespace vsurg::cli
