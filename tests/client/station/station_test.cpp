// The station against a real vsurg-server process: it survives the server restarting (the force
// fades while the server is gone, a new session starts when it is back), and the station and
// monitor binaries behave at their edges (a trainee's token cannot monitor; headless
// screenshots show the arm, twisted where it was grasped).
#include "client/station/station.h"

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>

#include <gtest/gtest.h>

#include "common/core/image.h"
#include "common/sim/cut_trainee.h"
#include "db/store.h"
#include "tests/support/press_and_hold.h"
#include "tests/support/processes.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::client {
namespace {

namespace fs = std::filesystem;

struct Tokens {
  std::string admin, trainee, instructor;
};

// A fresh store with an administrator, a trainee and an instructor.
Tokens MakeStore(const fs::path& db) {
  Tokens t;
  auto store = db::Store::Open({.path = db.string()});
  EXPECT_TRUE(store.ok());
  t.admin = (*store)->InitAdmin("root").value();
  EXPECT_TRUE((*store)->CreateUser("tia", db::Role::kTrainee, "A").ok());
  EXPECT_TRUE((*store)->CreateUser("ivo", db::Role::kInstructor, "").ok());
  t.trainee = (*store)->IssueToken("tia", "test").value();
  t.instructor = (*store)->IssueToken("ivo", "test").value();
  return t;
}

// A fresh folder, a store with MakeStore's users in it, and a server on them (declared in that
// order: each is made from the one before).
struct Site {
  test::TempDir dir;
  fs::path db;
  Tokens tokens;
  test::ServerProcess server;
  explicit Site(const std::string& name)
      : dir(name),
        db(dir / "vsurg.db"),
        tokens(MakeStore(db)),
        server(test::ServerProcess::Start(VSURG_SERVER_BINARY, dir, db)) {}
};

Remote RemoteTo(int port, const std::string& token) {
  Remote r;
  r.address = "127.0.0.1:" + std::to_string(port);
  r.channel = MakeChannel(r.address, nullptr);
  r.token = token;
  r.timeout_s = 3;
  return r;
}

// Asks `done` every 10 ms until it is true or `seconds` pass; true when done.

// Ticks the station every 10 ms until `done` or `seconds` pass; true when done.
template <typename F>
bool TickUntil(Station& station, double seconds, F done) {
  return test::Eventually(seconds, [&] {
    station.Tick();
    return done();
  });
}

// `fn` on the station's channel; false (and `fn` not run) while it has none.
template <typename F>
bool OnChannel(Station& station, F fn) {
  bool out = false;
  station.WithChannel([&](StationChannel& c, const StationStatus&) { out = fn(c); });
  return out;
}

TEST(StationTest, SurvivesTheServerRestartingWithTheForceFadedMeanwhile) {
  Site site("vsurg_station_restart");
  auto& [dir, db, tokens, server] = site;
  ASSERT_GT(server.grpc_port, 0);
  const int grpc_port = server.grpc_port, udp_port = server.udp_port;

  // Presses repeated for a minute (2 s each: in, hold, out): a new session after the restart
  // starts with the tissue at rest and the tip outside, as the proxy needs.
  std::vector<haptics::StylusSample> presses;
  const std::vector<haptics::StylusSample> one = test::PressAndHold(1.8);
  for (int k = 0; k < 30; ++k) {
    presses.insert(presses.end(), one.begin(), one.end());
    presses.insert(presses.end(), 200, one.front());  // lifted
  }
  ReplayDevice device(presses);
  StationConfig config;
  config.scene = "sphere-palpation-256";
  Station station(RemoteTo(grpc_port, tokens.trainee), &device, config);
  ASSERT_TRUE(TickUntil(station, 20, [&] {
    return OnChannel(station, [](StationChannel& c) {
      return c.stats().received > 800 && c.last_force().norm() > 0.3;
    });
  })) << station.status().last_error;
  const uint64_t first_session = station.status().session;
  EXPECT_EQ(station.status().generation, 1u);

  // The server goes down while the hand is pressing (a clean stop: the session is recorded as
  // aborted).
  ASSERT_TRUE(TickUntil(station, 5, [&] {
    return OnChannel(station, [](StationChannel& c) { return c.last_force().norm() > 0.4; });
  }));
  const size_t written_before = device.forces().size();
  EXPECT_EQ(server.Signal(SIGTERM), 0);
  ASSERT_TRUE(TickUntil(station, 10,
                        [&] { return station.status().state == StationState::kReconnecting; }));
  // The force never jumps: the contact's model was held through the silence (model_hold_s), or
  // ended at the station when the replayed hand lifted off, and when the station gave up on the
  // server (0.5 s of silence and a failed probe) it stopped the channel, which fades a held force
  // out over 50 cycles (StationChannelTest.StopFadesTheForceOutInsteadOfCuttingIt) and counts
  // that as a fade for want of answers.
  const std::vector<Eigen::Vector3d> forces = device.forces();
  EXPECT_GT(forces[written_before - 1].norm(), 0.3);
  const double step = device.limits().max_force_rate * 1e-3 * 1.0001;
  for (size_t i = written_before; i < forces.size(); ++i)
    ASSERT_LE((forces[i] - forces[i - 1]).norm(), step) << i;
  EXPECT_EQ(forces.back().norm(), 0.0);
  EXPECT_GE(station.total_stats().watchdog_fades, 1u) << "a fade for want of answers";
  EXPECT_FALSE(station.WithChannel([](StationChannel&, const StationStatus&) {}));

  // Meanwhile attempts fail and are retried; then the server is back on the same ports.
  EXPECT_FALSE(
      TickUntil(station, 1.0, [&] { return station.status().state == StationState::kLive; }));
  server = test::ServerProcess::Start(VSURG_SERVER_BINARY, dir, db, grpc_port, udp_port);
  ASSERT_EQ(server.grpc_port, grpc_port);
  // Until the server itself answers with a contact force: the station's own rendering can show
  // a force extrapolated by the local model while the new session's proxy has not yet met the
  // surface (a session started mid-press sees the tissue only after the next lift).
  StationView view;
  ASSERT_TRUE(TickUntil(station, 20, [&] {
    return OnChannel(station, [&](StationChannel& c) {
      c.TakeView(view);
      return c.stats().received > 300 && view.command.contact && view.command.force.norm() > 0.3;
    });
  })) << station.status().last_error;
  EXPECT_EQ(station.status().reconnects, 1);
  EXPECT_EQ(station.status().generation, 2u);
  EXPECT_NE(station.status().session, first_session);

  auto summary = station.Finish("test over");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->state, SessionState::kEnded);
  EXPECT_TRUE(summary->has_metrics);
  EXPECT_GT(summary->metrics.peak_force, 0.1);
  server.Signal(SIGTERM);
  auto store = db::Store::Open({.path = db.string()});
  ASSERT_TRUE(store.ok());
  EXPECT_EQ((*store)->GetSession(static_cast<int64_t>(first_session))->state,
            SessionState::kAborted);
}

// The render thread may stall for seconds (a first frame on a software renderer): the
// station's own supervisor thread notices the lost server and starts a new session meanwhile,
// with nobody calling Tick.
TEST(StationTest, ItsSupervisorReconnectsWhileTheOwnerThreadIsBusy) {
  Site site("vsurg_station_supervisor");
  auto& [dir, db, tokens, server] = site;
  ASSERT_GT(server.grpc_port, 0);
  const int grpc_port = server.grpc_port, udp_port = server.udp_port;
  ReplayDevice device(std::vector<haptics::StylusSample>(60000, test::PressAndHold(1).front()));
  StationConfig config;
  config.scene = "sphere-palpation-256";
  // Declared before the station, so the supervisor (stopped by the station's destructor)
  // never reports into a vector that is gone, whichever way the test ends.
  std::mutex seen_mutex;
  std::vector<std::pair<StationState, uint64_t>> seen;  // what on_change reported, in order
  Station station(RemoteTo(grpc_port, tokens.trainee), &device, config);
  station.StartSupervisor([&](const StationStatus& st) {
    std::lock_guard lock(seen_mutex);
    seen.emplace_back(st.state, st.session);
  });
  // From here the test thread only polls: it never ticks.
  ASSERT_TRUE(test::Eventually(20, [&] {
    return OnChannel(station, [](StationChannel& c) { return c.stats().received > 200; });
  })) << station.status().last_error;
  const uint64_t first = station.status().session;

  server.Signal(SIGKILL);  // a crash: the restarted server finds the session unfinished
  server = test::ServerProcess::Start(VSURG_SERVER_BINARY, dir, db, grpc_port, udp_port);
  ASSERT_EQ(server.grpc_port, grpc_port);
  // Within 5 s, while the owner is busy (as a stalled render thread would be): live again and
  // forces arriving on the new channel (live comes first: the first reply follows a tick later).
  // The supervisor reports a change after its tick has made it, so the wait includes the
  // report of the new session.
  const bool back = test::Eventually(5, [&] {
    const StationStatus st = station.status();
    if (st.state != StationState::kLive || st.reconnects != 1 ||
        !OnChannel(station, [](StationChannel& c) { return c.stats().received > 0; }))
      return false;
    std::lock_guard lock(seen_mutex);
    return !seen.empty() && seen.back() == std::make_pair(StationState::kLive, st.session);
  });
  const StationStatus now = station.status();
  EXPECT_TRUE(back) << "state " << static_cast<int>(now.state) << ": " << now.last_error;
  EXPECT_EQ(now.state, StationState::kLive) << now.last_error;
  EXPECT_EQ(now.reconnects, 1);
  EXPECT_NE(now.session, first);
  {
    std::lock_guard lock(seen_mutex);
    ASSERT_GE(seen.size(), 4u);
    EXPECT_EQ(seen[0].first, StationState::kConnecting);
    EXPECT_EQ(seen[1], std::make_pair(StationState::kLive, first));
    EXPECT_EQ(seen[2].first, StationState::kReconnecting);
    EXPECT_EQ(seen.back(), std::make_pair(StationState::kLive, now.session));
  }
  auto summary = station.Finish("test over");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->id, now.session);
  EXPECT_EQ(station.status().state, StationState::kFinished);
  server.Signal(SIGTERM);
}

// A server that is only slow is not a lost session. Frozen for 2 s (its gRPC port takes the
// connection and answers nothing, its UDP port is silent), as a loaded control plane and node
// can be: the station's probes time out and are asked again, and when the server answers the
// station goes on in the same session on the same channel, never starting another.
TEST(StationTest, KeepsItsSessionWhileTheServerIsOnlySlow) {
  Site site("vsurg_station_slow");
  auto& [dir, db, tokens, server] = site;
  ASSERT_GT(server.grpc_port, 0);
  ReplayDevice device(std::vector<haptics::StylusSample>(60000, test::PressAndHold(1).front()));
  StationConfig config;
  config.scene = "sphere-palpation-256";
  Station station(RemoteTo(server.grpc_port, tokens.trainee), &device, config);
  ASSERT_TRUE(TickUntil(station, 20, [&] {
    return OnChannel(station, [](StationChannel& c) { return c.stats().received > 200; });
  })) << station.status().last_error;
  const uint64_t session = station.status().session;

  ASSERT_EQ(server.Freeze(true), 0);
  // Silent (0.5 s), then a probe that waits its 1 s for an answer that never comes.
  const bool asked_again = TickUntil(station, 10, [&] {
    return station.status().last_error.find("asking again") != std::string::npos;
  });
  const StationStatus frozen = station.status();
  ASSERT_EQ(server.Freeze(false), 0);
  EXPECT_TRUE(asked_again) << frozen.last_error;
  EXPECT_EQ(frozen.state, StationState::kLive) << frozen.last_error;
  uint64_t received = 0;
  OnChannel(station, [&](StationChannel& c) { return (received = c.stats().received) > 0; });
  ASSERT_TRUE(TickUntil(station, 20, [&] {
    return OnChannel(station,
                     [&](StationChannel& c) { return c.stats().received > received + 200; });
  })) << station.status().last_error;
  const StationStatus after = station.status();
  EXPECT_EQ(after.state, StationState::kLive);
  EXPECT_EQ(after.session, session);
  EXPECT_EQ(after.generation, 1u) << "the same channel";
  EXPECT_EQ(after.reconnects, 0);
  auto summary = station.Finish("test over");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->id, session);
  EXPECT_EQ(summary->state, SessionState::kEnded);
  server.Signal(SIGTERM);
}

TEST(StationTest, ARefusedTokenFailsAtOnceInsteadOfRetrying) {
  Site site("vsurg_station_refused");
  auto& [dir, db, tokens, server] = site;
  ReplayDevice device(test::PressAndHold(1));
  Station bad_token(RemoteTo(server.grpc_port, "vst_not-a-token"), &device, {});
  EXPECT_TRUE(
      TickUntil(bad_token, 10, [&] { return bad_token.status().state == StationState::kFailed; }));
  EXPECT_NE(bad_token.status().last_error.find("create"), std::string::npos);
  StationConfig unknown;
  unknown.scene = "no-such-scene";
  Station bad_scene(RemoteTo(server.grpc_port, tokens.trainee), &device, unknown);
  EXPECT_TRUE(
      TickUntil(bad_scene, 10, [&] { return bad_scene.status().state == StationState::kFailed; }));
  EXPECT_EQ(device.forces().size(), 0u) << "no channel ran";
}

// Four-handed training from the station: an instructor's station joins a trainee's running
// session on a channel of its own (observing), guides at α 0.5 when asked (a bad α refused and
// said), and leaving hands the session back: still running on the trainee's one channel, whose
// record says how much was guided. An ended session is not joined (the station fails at once).
TEST(StationTest, AnInstructorsStationJoinsGuidesAndLeavesTheTraineesSession) {
  Site site("vsurg_station_instruct");
  auto& [dir, db, tokens, server] = site;
  ASSERT_GT(server.grpc_port, 0);
  auto received = [](Station& st) {
    uint64_t n = 0;
    OnChannel(st, [&](StationChannel& c) { return (n = c.stats().received) > 0; });
    return n;
  };
  ReplayDevice trainee_hand(test::PressAndHold(120));
  StationConfig config;
  config.scene = "sphere-palpation-256";
  Station trainee(RemoteTo(server.grpc_port, tokens.trainee), &trainee_hand, config);
  trainee.StartSupervisor();
  ASSERT_TRUE(test::Eventually(20, [&] { return received(trainee) > 200; }))
      << trainee.status().last_error;
  const uint64_t session = trainee.status().session;

  ReplayDevice instructor_hand(test::PressAndHold(120));
  StationConfig as_instructor = config;
  as_instructor.instruct = session;
  Station instructor(RemoteTo(server.grpc_port, tokens.instructor), &instructor_hand,
                     as_instructor);
  instructor.StartSupervisor();
  ASSERT_TRUE(test::Eventually(20, [&] { return received(instructor) > 200; }))
      << instructor.status().last_error;
  EXPECT_EQ(instructor.status().session, session);
  EXPECT_EQ(instructor.guide().mode, sim::GuideMode::kObserve);

  instructor.RequestGuide({sim::GuideMode::kGuide, 1.5});  // refused by the station itself
  ASSERT_TRUE(test::Eventually(10, [&] { return !instructor.guide_error().empty(); }));
  EXPECT_NE(instructor.guide_error().find("alpha"), std::string::npos) << instructor.guide_error();
  instructor.RequestGuide({sim::GuideMode::kGuide, 0.5});
  ASSERT_TRUE(test::Eventually(10, [&] {
    return instructor.guide().mode == sim::GuideMode::kGuide && instructor.guide_error().empty();
  })) << instructor.guide_error();
  EXPECT_DOUBLE_EQ(instructor.guide().alpha, 0.5);
  const uint64_t at_guide = received(trainee);
  ASSERT_TRUE(test::Eventually(30, [&] { return received(trainee) > at_guide + 1500; }));

  auto left = instructor.Finish("instructor done");
  ASSERT_TRUE(left.ok()) << left.error().message;
  EXPECT_EQ(left->id, session);
  EXPECT_TRUE(IsLive(left->state)) << "leaving does not end the trainee's trial";
  const uint64_t at_leave = received(trainee);
  ASSERT_TRUE(test::Eventually(20, [&] { return received(trainee) > at_leave + 500; }));
  EXPECT_EQ(trainee.status().generation, 1u) << "the trainee's one channel throughout";
  auto summary = trainee.Finish("test over");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->state, SessionState::kEnded);
  EXPECT_GT(summary->metrics.guided_share, 0.1);
  EXPECT_LT(summary->metrics.guided_share, 0.95);
  EXPECT_NEAR(summary->metrics.guided_alpha, 0.5, 0.1);

  // The session ended: joining it fails at once, with the reason.
  Station late(RemoteTo(server.grpc_port, tokens.instructor), &instructor_hand, as_instructor);
  EXPECT_TRUE(TickUntil(late, 10, [&] { return late.status().state == StationState::kFailed; }));
  EXPECT_NE(late.status().last_error.find("as its instructor"), std::string::npos)
      << late.status().last_error;
  server.Signal(SIGTERM);
}

// Two hands at one station, one session: the blade's device cuts the circle while the second
// device's grasper holds the piece up on a channel of its own; the second device lost mid-cut
// stops its channel alone and the cut goes on to the end.
TEST(StationTest, TwoDevicesCutWithOneHandAndHoldWithTheOtherInOneSession) {
  Site site("vsurg_station_two_hands");
  auto& [dir, db, tokens, server] = site;
  ASSERT_GT(server.grpc_port, 0);
  auto scene = sim::LoadScene(sim::ScenesDirectory() + "/pattern-cut.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  auto blade_plan = sim::CutTrainee(*scene, sim::TraineeStyle::kGood);
  auto grasp_plan = sim::GrasperTrainee(*scene);
  ASSERT_TRUE(blade_plan.ok() && grasp_plan.ok());
  ReplayDevice blade_hand(*blade_plan), grasper_hand(*grasp_plan);
  StationConfig config;
  config.scene = "pattern-cut";
  Station station(RemoteTo(server.grpc_port, tokens.trainee), &blade_hand, config);
  station.SetSecondDevice(&grasper_hand);
  station.StartSupervisor();
  const auto second_received = [&] {
    uint64_t n = 0;
    station.WithSecondChannel([&](StationChannel& c) { n = c.stats().received; });
    return n;
  };
  ASSERT_TRUE(test::Eventually(30, [&] { return second_received() > 1500; }))
      << station.status().last_error;
  const auto peak = [](const ReplayDevice& d) {
    double f = 0;
    for (const Eigen::Vector3d& v : d.forces()) f = std::max(f, v.norm());
    return f;
  };
  // The jaws took the piece and lifted it: the patch pulls them back.
  ASSERT_TRUE(test::Eventually(20, [&] { return peak(grasper_hand) > 0.2; }))
      << "grasper's peak " << peak(grasper_hand) << " N";
  EXPECT_LT(peak(grasper_hand), scene->haptics.limits.max_force);

  // Mid-cut the second device is lost: its channel stops, the first hand's goes on.
  ASSERT_TRUE(test::Eventually(30, [&] { return blade_hand.position() > 4000; }));
  station.DropSecondHand();
  EXPECT_FALSE(station.WithSecondChannel([](StationChannel&) {}));
  ASSERT_TRUE(test::Eventually(60, [&] { return blade_hand.finished(); }));
  EXPECT_EQ(station.status().generation, 1u) << "one session, one first-hand channel";
  auto summary = station.Finish("test over");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->state, SessionState::kEnded);
  EXPECT_TRUE(summary->metrics.completed);
  EXPECT_GT(summary->metrics.coverage, 0.9);
  server.Signal(SIGTERM);
}

// The binaries, as the demo runs them.
// The station's --help shows the bounds and defaults of the settings it fills, and the parser
// holds to them before anything opens (exit 2, the option named).
TEST(StationBinaryTest, ItsOptionsAreTheStationConfigsBounds) {
  const std::string station = VSURG_STATION_BINARY;
  const test::ShellRun help = test::Shell(station + " --help");
  ASSERT_EQ(help.code, 0) << help.out;
  const StationConfig c;
  const auto shows = [&](const std::string& option, double def, Range r) {
    return help.out.find(" (default " + NumberText(def) + ") (within " + r.Text() + ")",
                         help.out.find("--" + option + " ")) != std::string::npos;
  };
  EXPECT_TRUE(shows("realtime-priority", c.realtime_priority, StationConfig::kRealtimePriority))
      << help.out;
  EXPECT_TRUE(shows("model-hold", c.model_hold_s, StationConfig::kModelHoldS)) << help.out;
  EXPECT_TRUE(shows("deadband", c.deadband, StationConfig::kDeadband)) << help.out;
  for (const std::string& bad :
       {std::string("--model-hold 11"), std::string("--realtime-priority 100"),
        std::string("--deadband 1"), std::string("--fps 0"), std::string("--join 0")}) {
    const test::ShellRun r =
        test::Shell(station + " --server 127.0.0.1:1 --token t " + bad + " 2>&1");
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.out;
    EXPECT_NE(r.out.find(bad.substr(0, bad.find(' ')) + ": must be within"), std::string::npos)
        << bad << "\n"
        << r.out;
  }
}

TEST(StationBinaryTest, HeadlessScreenshotsShowTheTwistAndAMonitorNeedsAnInstructor) {
  Site site("vsurg_station_binary");
  auto& [dir, db, tokens, server] = site;
  const std::string remote = " --server 127.0.0.1:" + std::to_string(server.grpc_port);
  const std::string trajectory = (dir / "good.csv").string();
  ASSERT_EQ(test::Shell(std::string(VSURG_SIM_BINARY) + " trainee --scene arm-torsion --out " +
                        trajectory + " >/dev/null")
                .code,
            0);

  // An instructor follows in text while the trainee twists the arm.
  const std::string monitor_log = (dir / "monitor.txt").string();
  const std::string monitor = std::string(VSURG_MONITOR_BINARY) + " follow --text --print-hz 5" +
                              remote + " --token " + tokens.instructor + " > " + monitor_log +
                              " 2>&1 &";
  ASSERT_EQ(std::system(monitor.c_str()), 0);
  const std::string before = (dir / "before.png").string(), after = (dir / "after.png").string();
  const test::ShellRun station = test::Shell(
      std::string(VSURG_STATION_BINARY) + remote + " --token " + tokens.trainee +
      " --scene arm-torsion --trajectory " + trajectory + " --headless --width 480 --height 300" +
      " --screenshot-before " + before + " --screenshot " + after + " --screenshot-at 4.5 --json");
  ASSERT_EQ(station.code, 0) << station.out;
  const auto summary = nlohmann::json::parse(station.out);
  EXPECT_EQ(summary["state"], "ended");
  EXPECT_TRUE(summary["metrics"]["completed"].get<bool>());
  EXPECT_GT(summary["metrics"]["score"].get<double>(), 5.0);
  // The tissue's frames reached the station through the trial. How many depends on the pace of
  // the server's deformation thread: over a hundred on an idle machine, a few dozen under a
  // sanitizer beside other suites; the pictures below show what they moved.
  EXPECT_GE(summary["scene_chunks"].get<int>(), 5) << station.out;
  // --quality auto chose the trial's level from frames drawn before it (high probed first), and
  // the trial never went above that level.
  const auto level = [](const std::string& q) {
    return q == "low" ? 0 : q == "medium" ? 1 : q == "high" ? 2 : -1;
  };
  EXPECT_TRUE(summary["quality_probe_p90_ms"].contains("high")) << station.out;
  const int start = level(summary["quality_start"].get<std::string>());
  const int end = level(summary["quality_end"].get<std::string>());
  EXPECT_GE(end, 0);
  EXPECT_LE(end, start) << station.out;

  auto a = ReadRgbPng(before), b = ReadRgbPng(after);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->rgb.size(), size_t{480} * 300 * 3);
  // Not blank: the background is one colour; the arm covers a good part of the image.
  const unsigned char* corner = a->rgb.data() + (299 * 480 + 479) * 3;
  size_t not_background = 0, changed = 0;
  for (size_t i = 0; i < a->rgb.size(); i += 3) {
    if (std::abs(a->rgb[i] - corner[0]) + std::abs(a->rgb[i + 1] - corner[1]) +
            std::abs(a->rgb[i + 2] - corner[2]) >
        30)
      ++not_background;
    if (std::abs(a->rgb[i] - b->rgb[i]) + std::abs(a->rgb[i + 1] - b->rgb[i + 1]) +
            std::abs(a->rgb[i + 2] - b->rgb[i + 2]) >
        30)
      ++changed;
  }
  EXPECT_GT(not_background, a->rgb.size() / 3 / 5) << "the arm fills over a fifth of the view";
  EXPECT_GT(changed, 1000u) << "the twisted arm (and the HUD) must differ from the rest state";

  // The monitor saw the session end and printed live telemetry with the twist.
  std::string log;
  test::Eventually(10, [&] {
    std::ifstream in(monitor_log);
    log.assign(std::istreambuf_iterator<char>(in), {});
    return log.find(" ended:") != std::string::npos;
  });
  EXPECT_NE(log.find("state=running"), std::string::npos) << log;
  EXPECT_NE(log.find("twist_deg=45.0"), std::string::npos) << log;
  EXPECT_NE(log.find(" ended:"), std::string::npos) << log;

  // A trainee's token is refused by the monitor, with the reason and exit code 1.
  const test::ShellRun refused = test::Shell(
      std::string(VSURG_MONITOR_BINARY) + " follow --text" + remote + " --token " + tokens.trainee +
      " --session " + std::to_string(summary["session"].get<int>()) + " 2>&1");
  EXPECT_EQ(refused.code, 1);
  EXPECT_NE(refused.out.find("may not call MonitorService/Watch"), std::string::npos)
      << refused.out;
  EXPECT_EQ(test::Shell(std::string(VSURG_MONITOR_BINARY) + " list" + remote + " --token " +
                        tokens.trainee + " >/dev/null 2>&1")
                .code,
            0)
      << "a trainee may list their own sessions";
}

// The GLFW window itself, under a virtual X server (Xvfb): the same view as headless.
TEST(StationBinaryTest, OpensItsWindowUnderXvfb) {
  if (test::Shell("command -v xvfb-run >/dev/null").code != 0) GTEST_SKIP() << "no xvfb-run";
  Site site("vsurg_station_window");
  auto& [dir, db, tokens, server] = site;
  const std::string trajectory = (dir / "good.csv").string(), shot = (dir / "window.png").string();
  ASSERT_EQ(test::Shell(std::string(VSURG_SIM_BINARY) + " trainee --scene arm-torsion --out " +
                        trajectory + " >/dev/null")
                .code,
            0);
  const test::ShellRun run =
      test::Shell("xvfb-run -a -s '-screen 0 1024x768x24' " + std::string(VSURG_STATION_BINARY) +
                  " --server 127.0.0.1:" + std::to_string(server.grpc_port) + " --token " +
                  tokens.trainee + " --trajectory " + trajectory +
                  " --duration 1.5 --width 400 --height 300 --screenshot " + shot + " 2>&1");
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.out.find("ended"), std::string::npos) << run.out;
  auto image = ReadRgbPng(shot);
  ASSERT_TRUE(image.ok()) << image.error().message;
  EXPECT_EQ(image->width, 400);
  std::set<int> colours;
  for (size_t i = 0; i + 2 < image->rgb.size(); i += 3)
    colours.insert(image->rgb[i] << 16 | image->rgb[i + 1] << 8 | image->rgb[i + 2]);
  EXPECT_GT(colours.size(), 50u) << "a shaded arm, not an empty window";
}

// The keyboard-and-mouse device in the real window: X key events (xdotool under Xvfb) move the
// stylus, and the server's trial sees the path: D held about 1 s, then E about 0.5 s, at 5 cm/s.
// The station runs until the keys are done and is then stopped (SIGINT), so a slow start under a
// sanitizer or a loaded machine cannot end the trial before the keys are pressed. The keys wait
// for the session to be live (the station's log): the window's events are taken between the
// trial's frames, and the frames before it (the first one, the quality probe) take seconds under
// ASan on a loaded machine, longer than the keys did, which then came and went unseen.
TEST(StationBinaryTest, KeysInTheWindowMoveTheStylus) {
  if (test::Shell("command -v xvfb-run >/dev/null && command -v xdotool >/dev/null").code != 0)
    GTEST_SKIP() << "no xvfb-run or xdotool";
  Site site("vsurg_station_keys");
  auto& [dir, db, tokens, server] = site;
  const std::string summary = (dir / "summary.json").string(), script = (dir / "keys.sh").string();
  const std::string log = (dir / "station.log").string();
  std::ofstream(script) << VSURG_STATION_BINARY << " --server 127.0.0.1:" << server.grpc_port
                        << " --token " << tokens.trainee
                        << " --device keyboard-mouse --duration 60 --width 400 --height 300"
                        << " --json > " << summary << " 2> " << log << " &\n"
                        << "pid=$!\n"
                        << "w=$(timeout 20 xdotool search --sync --name 'vsurg station')\n"
                        << "for i in $(seq 600); do grep -q state=live " << log
                        << " && break; sleep 0.1; done\n"
                        << "sleep 0.5\n"
                        << "xdotool windowactivate --sync $w 2>/dev/null || xdotool windowfocus "
                           "--sync $w\n"
                        << "xdotool keydown d; sleep 1; xdotool keyup d\n"
                        << "xdotool keydown e; sleep 0.5; xdotool keyup e\n"
                        << "sleep 0.3\n"       // the last key's motion reaches the server
                        << "kill -INT $pid\n"  // ended after the keys, however slow the start
                        << "wait $pid\n";
  const test::ShellRun run =
      test::Shell("xvfb-run -a -s '-screen 0 1024x768x24' bash " + script + " 2>&1");
  ASSERT_EQ(run.code, 0) << run.out;
  std::ifstream in(summary);
  const auto j = nlohmann::json::parse(in, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << run.out;
  EXPECT_EQ(j["state"], "ended");
  const double path = j["metrics"]["path_length"].get<double>();
  EXPECT_GT(path, 0.03) << "the keys must have moved the stylus (expected about 7.5 cm)";
  EXPECT_LT(path, 0.2);
}

}  // namespace
}  // namespace vsurg::client
