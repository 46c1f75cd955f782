// vsurg-bench's round-trip commands on real sockets on loopback: the floor (udp-floor, a plain
// echo) and ours (haptic-rtt, the UDP endpoint with a simulation per station), with the same
// stations, pacing and JSON, so bench/peers/rtt.sh can set one against the other.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/support/processes.h"

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

}  // namespace
}  // namespace vsurg
