// The whole demo flow (deploy/demo_flow.sh) as the three kinds of users run it, checked from
// its outputs: the station twisted the arm over UDP and its session was recorded with metrics,
// the monitor printed live telemetry, an instructor's station guided a second trial, three
// evaluator groups' scores make the weighted report, the CSV export holds them, the screenshots
// show the arm and differ where it was twisted, and nothing is left running.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/core/image.h"
#include "tests/support/processes.h"
#include "tests/support/temp_dir.h"

namespace vsurg {
namespace {

namespace fs = std::filesystem;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(DemoFlowTest, TraineeInstructorEvaluatorsAndAdministratorEndToEnd) {
  const test::TempDir out("e2e");
  const test::ShellRun run = test::Shell(std::string(VSURG_SOURCE_DIR) + "/deploy/demo_flow.sh " +
                                         VSURG_BIN_DIR + " " + out.string() + " 2>&1");
  ASSERT_EQ(run.code, 0) << run.out;

  // The station: one session, twisted to the target and held, every datagram answered.
  const auto station = nlohmann::json::parse(Slurp(out / "station.json"));
  EXPECT_EQ(station["state"], "ended");
  EXPECT_EQ(station["end_reason"], "completed");
  EXPECT_TRUE(station["metrics_recorded"].get<bool>());
  EXPECT_TRUE(station["metrics"]["completed"].get<bool>());
  EXPECT_LT(station["metrics"]["task_error"].get<double>(), 0.0873);  // within 5°
  EXPECT_GT(station["received"].get<double>(), 0.95 * station["sent"].get<double>());
  // The arm's frames reached the station while it turned: each one chunk (the twist's numbers, as
  // the station holds the same arm), some 60 a second while it changes on an idle machine.
  EXPECT_GE(station["scene_chunks"].get<int>(), 20);

  // Four hands: the instructor's station joined the trainee's second trial and left it to her;
  // her record says how much of it was guided (observe, guide at 0.5, take over, hand back).
  const auto guided = nlohmann::json::parse(Slurp(out / "station-guided.json"));
  const auto instructor = nlohmann::json::parse(Slurp(out / "station-instructor.json"));
  EXPECT_EQ(guided["state"], "ended");
  EXPECT_EQ(instructor["session"], guided["session"]);
  EXPECT_GT(instructor["received"].get<double>(), 1000);
  EXPECT_GT(guided["metrics"]["guided_share"].get<double>(), 0.1);
  EXPECT_LT(guided["metrics"]["guided_share"].get<double>(), 0.9);
  EXPECT_GT(guided["metrics"]["guided_alpha"].get<double>(), 0.3);

  // Two hands at one station: the blade cut the circle out while the second device's grasper
  // held the piece on its own channel and felt its pull.
  const auto cut = nlohmann::json::parse(Slurp(out / "station-cut.json"));
  EXPECT_EQ(cut["state"], "ended");
  EXPECT_TRUE(cut["metrics"]["completed"].get<bool>());
  EXPECT_GT(cut["metrics"]["coverage"].get<double>(), 0.9);
  EXPECT_GT(cut["second_hand"]["received"].get<double>(), 1000);
  EXPECT_GT(cut["second_hand"]["max_force_n"].get<double>(), 0.2);

  // The instructor's terminal: live lines while twisting, then the end of the session.
  const std::string monitor = Slurp(out / "monitor.log");
  EXPECT_GT(Count(monitor, "state=running"), 5u) << monitor;
  EXPECT_NE(monitor.find("twist_deg=45.0"), std::string::npos) << monitor;
  EXPECT_NE(monitor.find("grasping=1"), std::string::npos);
  EXPECT_NE(monitor.find(" ended:"), std::string::npos);

  // The administrator's report of the session: three groups, each index, the comprehensive
  // score (the coil-spring paper eq. 11) of 0.15·… weights over the group-weighted means; and the
  // metrics.
  EXPECT_NE(run.out.find("3 raters (intern 1, associate_chief 1, chief 1)"), std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("comprehensive N 8.418"), std::string::npos) << run.out;
  // Over the network the trial scores what the same trajectory scores replayed offline
  // (vsurg-sim run: 10.0), the station clock's jitter notwithstanding.
  EXPECT_NE(run.out.find("tia\tarm-torsion\tended\t10.0\tyes"), std::string::npos) << run.out;
  const test::ShellRun offline =
      test::Shell(std::string(VSURG_BIN_DIR) + "/vsurg-sim run --scene arm-torsion --trajectory " +
                  (out / "twist-good.csv").string() + " --json");
  ASSERT_EQ(offline.code, 0);
  EXPECT_NEAR(nlohmann::json::parse(offline.out)["metrics"]["score"].get<double>(),
              station["metrics"]["score"].get<double>(), 0.05);

  // The export: the session's 3 × 9 scores and the 120 × 9 model scores, with a header.
  const std::string csv = Slurp(out / "scores.csv");
  EXPECT_EQ(Count(csv, "\n"), 1u + 27 + 1080);
  EXPECT_EQ(Count(csv, ",session,1,tia,"), 27u);

  // Screenshots: the arm fills a good part of the view, and twisting it changed the image.
  auto before = ReadRgbPng((out / "station-before.png").string());
  auto twisted = ReadRgbPng((out / "station-twisted.png").string());
  auto monitor_view = ReadRgbPng((out / "monitor-view.png").string());
  ASSERT_TRUE(before.ok() && twisted.ok() && monitor_view.ok());
  size_t arm = 0, changed = 0;
  const unsigned char* bg = before->rgb.data() + before->rgb.size() - 3;  // bottom-right corner
  for (size_t i = 0; i + 2 < before->rgb.size(); i += 3) {
    int d_bg = 0, d_twist = 0;
    for (int k = 0; k < 3; ++k) {
      d_bg += std::abs(before->rgb[i + k] - bg[k]);
      d_twist += std::abs(before->rgb[i + k] - twisted->rgb[i + k]);
    }
    arm += d_bg > 30;
    changed += d_twist > 30;
  }
  const size_t pixels = before->rgb.size() / 3;
  EXPECT_GT(arm, pixels / 5);
  EXPECT_GT(changed, pixels / 100);
  EXPECT_EQ(monitor_view->width, 960);

  // Nothing left behind: the flow's server is gone (its log ends with a clean stop).
  const std::string log = Slurp(out / "server.log");
  EXPECT_NE(log.find("event=stopped"), std::string::npos) << log;
  EXPECT_EQ(test::Shell("pgrep -f 'vsurg-(station|monitor).*" + out.string() + "' >/dev/null").code,
            1);
  const size_t at = run.out.find("vsurg-server pid ");
  ASSERT_NE(at, std::string::npos);
  const int server_pid = std::stoi(run.out.substr(at + 17));
  EXPECT_NE(::kill(server_pid, 0), 0) << "vsurg-server " << server_pid << " still runs";
}

}  // namespace
}  // namespace vsurg
