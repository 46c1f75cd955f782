// One site as real processes on loopback (deploy/cluster_flow.sh): PostgreSQL, two control
// replicas, three simulation nodes, 24 replaying stations; a node frozen past its lease and
// resumed, a second process under a live node's name and one whose certificate names another
// node (the internal API runs mutual TLS), then a simulation node and a control replica killed
// with SIGKILL. The script measures; this test holds it to the site's promised bounds.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/support/temp_dir.h"

namespace {

namespace fs = std::filesystem;

// "sim-0=8 sim-1=8 sim-2=8 " → {sim-0: 8, …}
std::map<std::string, int> Spread(const std::string& text) {
  std::map<std::string, int> out;
  std::istringstream in(text);
  std::string item;
  while (in >> item) {
    const auto eq = item.find('=');
    if (eq != std::string::npos) out[item.substr(0, eq)] = std::stoi(item.substr(eq + 1));
  }
  return out;
}

TEST(ClusterTest, PlacementNodeLossAndControlLossOnPostgres) {
  const vsurg::test::TempDir out("cluster");
  const std::string cmd = std::string(VSURG_SOURCE_DIR) + "/deploy/cluster_flow.sh " +
                          VSURG_BIN_DIR + " " + out.string() + " 24 > " +
                          (out / "flow.log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "see " << (out / "flow.log").string();
  std::ifstream in(out / "cluster.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << "see " << (out / "flow.log").string();

  // Every session placed, spread within one session of each other.
  const auto spread = Spread(j["spread"].get<std::string>());
  ASSERT_EQ(spread.size(), 3u) << j.dump();
  int total = 0, lo = 1 << 30, hi = 0;
  for (const auto& [node, n] : spread) total += n, lo = std::min(lo, n), hi = std::max(hi, n);
  EXPECT_EQ(total, 24);
  EXPECT_LE(hi - lo, 1) << j["spread"];

  // A node killed: its sessions aborted, its stations back on the others within 3 s, their
  // force faded by the watchdog meanwhile and never above the device's 3.3 N.
  const int victims = j["victims"].get<int>();
  EXPECT_GT(victims, 0);
  EXPECT_EQ(j["aborted"].get<int>(), victims);
  EXPECT_EQ(j["moved"].get<int>(), victims);
  EXPECT_GT(j["back_ms"].get<int>(), 0);
  EXPECT_LE(j["back_ms"].get<int>(), 3000);
  const auto after = Spread(j["spread_after"].get<std::string>());
  EXPECT_EQ(after.count("sim-0"), 0u);
  // Every station of the frozen node and of the killed one came back once per loss (a station
  // moved off sim-1 onto sim-0 and killed there comes back twice), each with its force faded
  // meanwhile and never above the device's 3.3 N, compared exactly (the station clamps in the
  // arithmetic this check uses; a re-placed session ramps in from zero). Each session given up
  // was aborted with its node, except that on a machine so loaded that the control plane answers
  // no probe for 5 s a station gives its session up as unanswered and starts another; nothing
  // else makes a station start again.
  const int frozen = j["frozen_victims"].get<int>();
  const int unanswered = j["drops_unanswered"].get<int>();
  EXPECT_EQ(j["drops_other"].get<int>(), 0) << "see " << (out / "drops.txt").string();
  EXPECT_LE(j["drops_aborted"].get<int>(), victims + frozen);
  EXPECT_GE(j["reconnects"].get<int>(), victims + frozen);
  EXPECT_LE(j["reconnects"].get<int>(), victims + frozen + unanswered);
  EXPECT_EQ(j["reconnected_faded"].get<int>(), j["reconnected"].get<int>());
  EXPECT_GE(j["reconnected"].get<int>(), std::max(victims, frozen));
  EXPECT_LE(j["max_force_n"].get<double>(), 3.3);

  // Chaos a: a node frozen past its lease and resumed serves none of its old sessions again:
  // they stay aborted with no trial recorded, it took its name again under a new epoch, and no
  // trainee ever had two live sessions.
  EXPECT_GT(frozen, 0);
  EXPECT_EQ(j["frozen_not_aborted"].get<int>(), 0);
  EXPECT_EQ(j["frozen_trials"].get<int>(), 0);
  EXPECT_GE(j["lease_lost"].get<int>(), 1);
  EXPECT_EQ(j["reacquired"].get<int>(), 1);
  EXPECT_EQ(j["max_live_per_trainee"].get<int>(), 1);
  // Chaos b: a second process under a live node's name is refused and takes nothing.
  EXPECT_NE(j["twin_rc"].get<int>(), 0);
  EXPECT_NE(j["twin_rc"].get<int>(), 124) << "the twin hung instead of being refused";
  EXPECT_EQ(j["twin_refused"].get<int>(), 1);
  EXPECT_EQ(j["twin_kept"].get<int>(), 1);
  // Every role serves its Prometheus metrics, and they move (a node's forces, its lease).
  EXPECT_EQ(j["metrics_ok"].get<int>(), 1);
  // A node told to log JSON wrote only JSON lines, each about a session carrying its id.
  EXPECT_EQ(j["json_log_ok"].get<int>(), 1);
  // The internal API runs mutual TLS: a site certificate naming another node takes no name.
  EXPECT_NE(j["rogue_rc"].get<int>(), 0);
  EXPECT_NE(j["rogue_rc"].get<int>(), 124) << "the rogue hung instead of being refused";
  EXPECT_EQ(j["rogue_refused"].get<int>(), 1);

  // A control replica killed during a burst: nothing acknowledged is lost; the client's retry
  // on the other replica stores the rest exactly once.
  EXPECT_GT(j["acked"].get<int>(), 0);
  EXPECT_EQ(j["acked_missing"].get<int>(), 0);
  EXPECT_EQ(j["stored"].get<int>(), 400);

  // The surviving replica shows every live session to vsurg-monitor and the dashboard.
  EXPECT_EQ(j["monitor_running"].get<int>(), 24);
  EXPECT_EQ(j["dashboard_running"].get<int>(), 24);
}

// A rolling restart of every node of a 3-node site with 24 replaying stations
// (deploy/rolling_restart.sh): each node in turn drains on SIGTERM, moving its live sessions to
// the others, exits and is started again. No session is lost (one per station, none aborted,
// none created again), every trial is recorded once, every station followed its session to its
// new node(s) without a reconnection, and the longest force gap is measured.
TEST(ClusterTest, ARollingRestartOfEveryNodeLosesNoSessionAndNoTrial) {
  const vsurg::test::TempDir out("rolling");
  const std::string cmd = std::string(VSURG_SOURCE_DIR) + "/deploy/rolling_restart.sh " +
                          VSURG_BIN_DIR + " " + out.string() + " 24 > " +
                          (out / "flow.log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "see " << (out / "flow.log").string();
  std::ifstream in(out / "rolling.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << "see " << (out / "flow.log").string();
  EXPECT_EQ(j["summaries"].get<int>(), 24) << j.dump();
  // No session aborted by the site, every session's trial recorded exactly once, and each
  // station ending its own session.
  EXPECT_EQ(j["aborted"].get<int>(), 0);
  EXPECT_EQ(j["trials"].get<int>(), j["sessions"].get<int>());
  EXPECT_EQ(j["trial_twice"].get<int>(), 0);
  EXPECT_EQ(j["ended"].get<int>(), 24);
  EXPECT_EQ(j["migration_failed"].get<int>(), 0);
  // Every session lived on some node when it drained: each moved at least once, and its station
  // followed (a session moved twice before its station noticed is followed once). Unloaded, no
  // station reconnects: 24 sessions, one each, every one followed (docs/SCALING.md). On a
  // machine so loaded that the control plane answers no probe for 5 s (two CPU hogs beside the
  // 24 stations, the site and PostgreSQL on two cores), a station may give its session up and
  // start another: then the old one is recorded as disconnected, with its trial, never aborted
  // and never lost; and a Create it gave up waiting for is aborted at once as abandoned, never
  // started (ClusterTest.ASessionReadyAfterItsCreatorStoppedWaitingIsAbortedAtOnce).
  EXPECT_GE(j["migrated"].get<int>(), 24);
  EXPECT_GE(j["moves"].get<int>(), 1) << "no station followed its session";
  EXPECT_LE(j["moves"].get<int>(), j["migrated"].get<int>());
  EXPECT_GE(j["moves"].get<int>() + j["reconnects"].get<int>(), 24);
  EXPECT_EQ(j["sessions"].get<int>(), 24 + j["disconnected"].get<int>() + j["abandoned"].get<int>())
      << "a session beyond one per station that did not end recorded";
  // The longest force gap is measured (docs/SCALING.md), not bounded here: it is wall-clock time
  // on a shared machine.
  EXPECT_GT(j["longest_gap_ms"].get<int>(), 0);
}

}  // namespace
