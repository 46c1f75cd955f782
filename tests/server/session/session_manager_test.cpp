// The session manager's state machine, directly (server/session/session_manager.h): every
// transition in its table, with a real store, a real UDP endpoint on loopback and a station
// played by a raw socket; the endpoint's and the manager's clocks are manual, so stalls,
// disconnections and start timeouts happen when the test says, not after real waits.
#include "server/session/session_manager.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "common/core/clock.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"
#include "tests/support/press_and_hold.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::server {
namespace {

namespace fs = std::filesystem;
namespace asio = boost::asio;
using asio::ip::udp;

class SessionManagerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_ = db::Store::Open({.path = (dir_ / "vsurg.db").string()}).value();
    EndpointOptions eo;
    eo.clock = &endpoint_clock_;
    eo.stall_after_s = 0.5;
    eo.disconnect_after_s = 5;
    eo.visual_hz = 0;
    endpoint_ = UdpEndpoint::Create(eo).value();
    SessionManagerOptions so;
    so.clock = &clock_;
    so.telemetry_hz = 100;  // Pump runs often: the test waits less
    so.start_timeout_s = 60;
    so.max_sessions_per_user = 2;
    sessions_ = SessionManager::Open(*store_, endpoint_.get(), so).value();
  }
  void TearDown() override {
    sessions_.reset();
    endpoint_.reset();
    store_.reset();
  }

  // The state the manager reports, once it is `want` (the sampler applies events on its tick).
  SessionState WaitFor(uint64_t id, SessionState want) {
    test::Eventually(10, [&] { return sessions_->Get(id)->state == want; });
    return sessions_->Get(id)->state;
  }
  // One stylus datagram from the station, answered; stamped `time` on the station's clock (by
  // default seq ms, a 1 kHz station).
  void Drive(const CreatedSession& s, uint64_t seq, double time = -1, wire::StylusMessage m = {}) {
    m.sample.time = time >= 0 ? time : 1e-3 * static_cast<double>(seq);
    if (m.sample.position.isZero()) m.sample.position = Eigen::Vector3d(0, 0, 0.2);  // above
    std::array<uint8_t, wire::kMaxDatagram> buf{};
    const uint64_t id = static_cast<uint64_t>(s.record.id);
    const size_t n =
        codec_.EncodeStylus(m, {wire::kProtocolVersion, wire::PayloadType::kStylusState, id, seq},
                            wire::Authenticator(s.key), buf);
    socket_.send_to(asio::buffer(buf.data(), n), udp::endpoint(loopback_, s.udp_port));
    std::array<uint8_t, 2048> in{};
    udp::endpoint from;
    socket_.receive_from(asio::buffer(in), from);  // blocking: the endpoint answers at once
  }
  // Quiet for `s` seconds on the endpoint's clock, then its timeout check.
  void Quiet(double s) {
    endpoint_clock_.Advance(s);
    endpoint_->CheckTimeoutsNow();
  }

  test::TempDir dir_{"sessions"};  // first: it outlives the store in it
  ManualClock clock_, endpoint_clock_;
  std::unique_ptr<db::Store> store_;
  std::unique_ptr<UdpEndpoint> endpoint_;
  std::unique_ptr<SessionManager> sessions_;
  asio::io_context io_;
  asio::ip::address loopback_ = asio::ip::make_address("127.0.0.1");
  udp::socket socket_{io_, udp::endpoint(loopback_, 0)};
  wire::Codec codec_;
};

// A live session's handoff (live migration) reads back as it was sent; bytes that are cut,
// corrupted or claim to inflate past the bound are refused with why, never allocated blindly.
TEST(SessionHandoffTest, AHandoffReadsBackWholeAndBrokenOnesAreRefused) {
  SessionHandoff h;
  h.id = 42;
  h.trainee = "tina";
  h.scene = "arm-torsion";
  h.state = SessionState::kStalled;
  h.created_us = 10;
  h.started_us = 20;
  h.key = std::string(32, 'k');
  h.task.target = 0.5;
  h.task.kind = scoring::TaskKind::kTwist;
  h.simulation = std::string(100000, '\x01');  // compresses: the frames of a held twist do
  h.trace = "trace";
  h.applied = 1234;
  h.lost = 5;
  h.span_s = 1.5;
  h.rendered_peak_n = 2.5;
  h.from_node = "sim-0";
  h.from_epoch = 3;
  const std::string bytes = h.Bytes();
  EXPECT_LT(bytes.size(), 10000u) << "sent deflated";
  auto back = SessionHandoff::FromBytes(bytes);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->id, 42);
  EXPECT_EQ(back->trainee, "tina");
  EXPECT_EQ(back->state, SessionState::kStalled);
  EXPECT_EQ(back->key, h.key);
  EXPECT_EQ(back->task.target, 0.5);
  EXPECT_EQ(back->task.kind, scoring::TaskKind::kTwist);
  EXPECT_FALSE(back->task.tolerance.has_value());
  EXPECT_EQ(back->simulation, h.simulation);
  EXPECT_EQ(back->applied, 1234u);
  EXPECT_EQ(back->span_s, 1.5);
  EXPECT_EQ(back->from_node, "sim-0");
  EXPECT_EQ(back->from_epoch, 3);

  std::string bomb = bytes;
  const uint64_t huge = 1ull << 40;
  std::memcpy(bomb.data(), &huge, 8);
  std::string corrupt = bytes;
  corrupt[bytes.size() / 2] = static_cast<char>(corrupt[bytes.size() / 2] ^ 0x5a);
  SessionHandoff keyless = h;
  keyless.key = "short";
  for (const std::string& bad :
       {std::string(), bytes.substr(0, 5), bytes.substr(0, bytes.size() - 3), bomb, corrupt,
        keyless.Bytes(), std::string(64, 'x')}) {
    auto r = SessionHandoff::FromBytes(bad);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().field, "handoff") << r.error().message;
  }
}

TEST_F(SessionManagerTest, TheTrialRecordsWhatTheStationRenderedAndHowTheLinkHeld) {
  auto s = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(s.ok());
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  ASSERT_TRUE(sessions_->Start(id).ok());
  const struct {
    uint64_t seq;
    double peak, over;
  } sent[] = {{1, 0.5, 0}, {2, 1.7, 0.02}, {3, 1.2, 0.015}, {5, 1.6, 0.02}};  // 4 lost; 3 late
  for (const auto& d : sent) {
    wire::StylusMessage m;
    m.rtt_us = 25000;
    m.jitter_us = 1500;
    m.rendered_peak_n = d.peak;
    m.rendered_over_limit_s = d.over;
    Drive(*s, d.seq, -1, m);
    endpoint_clock_.Advance(0.01);
  }
  ASSERT_TRUE(sessions_->Stop(id, "done").ok());
  const auto metrics = store_->GetTrialMetrics(s->record.id);
  ASSERT_TRUE(metrics.ok() && metrics->has_value());
  const scoring::LinkFigures& l = (*metrics)->link;
  EXPECT_NEAR(l.station_peak_force, 1.7, 1e-6);  // a later, lower report does not lower it
  EXPECT_NEAR(l.station_time_over_limit, 0.02, 1e-6);
  EXPECT_NEAR(l.rtt_ms, 25, 1e-3);
  EXPECT_NEAR(l.jitter_ms, 1.5, 1e-3);
  EXPECT_NEAR(l.loss, 0.2, 1e-9);          // 4 applied, sequence 4 never seen
  EXPECT_NEAR(l.rate_hz, 4 / 0.03, 1e-6);  // 4 applied over the 30 ms between first and last
}

// The station's own figures are its word: the record bounds them by what the server can check. A
// station reporting 3.4e38 N and 3.4e38 s over the limit in a 30-ms trial is recorded at the most
// any device renders (50 N) and at the time its datagrams came over.
TEST_F(SessionManagerTest, TheRecordBoundsWhatTheStationSaysItRendered) {
  auto s = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(s.ok());
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  ASSERT_TRUE(sessions_->Start(id).ok());
  for (uint64_t seq = 1; seq <= 4; ++seq) {
    wire::StylusMessage m;
    m.rendered_peak_n = 3.4e38f;
    m.rendered_over_limit_s = 3.4e38f;
    Drive(*s, seq, -1, m);
    endpoint_clock_.Advance(0.01);
  }
  ASSERT_TRUE(sessions_->Stop(id, "done").ok());
  const auto metrics = store_->GetTrialMetrics(s->record.id);
  ASSERT_TRUE(metrics.ok() && metrics->has_value());
  const scoring::LinkFigures& l = (*metrics)->link;
  EXPECT_EQ(l.station_peak_force, 50);
  EXPECT_NEAR(l.station_time_over_limit, 0.03, 1e-6);  // the first to the last datagram
}

// An exercise's task settings are the task the session scores: the same 1.5-s press (3 mm
// into the sphere, held) completes a press to 1 mm within 20 mm held 0.3 s, does not complete the
// scene's own press (5 mm within 1 mm, held 2 s), and stays longer over a 0.5 N force limit than
// over the scene's 2 N.
TEST_F(SessionManagerTest, AnExercisesTaskSettingsAreTheTaskTheSessionScores) {
  const auto trial = [&](const scoring::TaskSettings& task) {
    auto s = sessions_->Create("tina", "sphere-palpation-256", task);
    EXPECT_TRUE(s.ok()) << s.error().message;
    const uint64_t id = static_cast<uint64_t>(s->record.id);
    EXPECT_TRUE(sessions_->Start(id).ok());
    uint64_t seq = 0;
    for (const haptics::StylusSample& sample : test::PressAndHold(1.5)) {
      wire::StylusMessage m;
      m.sample = sample;
      Drive(*s, ++seq, -1, m);
      endpoint_clock_.Advance(1e-3);  // a 1 kHz station (the endpoint limits each one's rate)
    }
    EXPECT_TRUE(sessions_->Stop(id, "done").ok());
    return store_->GetTrialMetrics(s->record.id).value().value();
  };
  const scoring::TrialMetrics scene = trial({});
  scoring::TaskSettings easy;
  easy.kind = scoring::TaskKind::kPress;
  easy.target = 0.001;
  easy.tolerance = 0.02;
  easy.hold_s = 0.3;
  easy.force_limit = 10;
  const scoring::TrialMetrics easy_trial = trial(easy);
  scoring::TaskSettings strict;
  strict.force_limit = 0.5;
  const scoring::TrialMetrics strict_trial = trial(strict);
  EXPECT_FALSE(scene.completed);  // 2 s of hold asked, 1.5 s given
  EXPECT_TRUE(easy_trial.completed);
  EXPECT_EQ(easy_trial.time_over_force_limit, 0);
  // The press pushes ~2 N (more in a slow sanitizer build, where the tissue's deformation lags
  // the haptic path): over 0.5 N for most of its 1.2-s hold, longer than over the scene's 2 N.
  EXPECT_GT(strict_trial.peak_force, 0.5);
  EXPECT_GT(strict_trial.time_over_force_limit, 0.9);
  EXPECT_GT(strict_trial.time_over_force_limit, scene.time_over_force_limit);
  // Settings that do not fit the scene's task are refused by name, and no session is made.
  scoring::TaskSettings twist;
  twist.kind = scoring::TaskKind::kTwist;
  twist.target = 1.0;
  auto refused = sessions_->Create("tina", "sphere-palpation-256", twist);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(refused.error().field, "task.target_depth_m");
  scoring::TaskSettings short_limit;
  short_limit.time_limit = 1.5;  // the scene holds 2 s
  EXPECT_EQ(sessions_->Create("tina", "sphere-palpation-256", short_limit).error().field,
            "task.time_limit_s");
}

TEST_F(SessionManagerTest, ADrivenSessionKeepsItsRecordWhileLiveAndOnceEnded) {
  auto s = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(s.ok());
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  ASSERT_TRUE(sessions_->Start(id).ok());
  // The station drives until the sampler has kept a few ticks of it (progress, not a sleep).
  uint64_t seq = 0;
  auto kept = [&] {
    auto j = nlohmann::json::parse(sessions_->Trace(id).value());
    return j["series"]["time_s"].size();
  };
  test::Eventually(20, [&] {
    for (int i = 0; i < 5; ++i) Drive(*s, ++seq);
    return kept() >= 3;
  });
  const size_t live_samples = kept();
  ASSERT_GE(live_samples, 3u);
  ASSERT_TRUE(sessions_->Stop(id, "done").ok());
  EXPECT_EQ(sessions_->Trace(id).error().code, ErrorCode::kNotFound);  // no longer live
  const auto j = nlohmann::json::parse(store_->GetSessionTrace(s->record.id).value());
  const auto& t = j["series"]["time_s"];
  EXPECT_GE(t.size(), live_samples);
  for (size_t i = 1; i < t.size(); ++i) EXPECT_GT(t[i].get<double>(), t[i - 1].get<double>());
  EXPECT_LE(t.back().get<double>(), 1e-3 * static_cast<double>(seq) + 1e-9);  // station time
  EXPECT_EQ(j["series"]["force_n"].size(), t.size());
  EXPECT_GT(j["rest"]["positions_mm"].size(), 300u);  // the sphere's surface, 3 per vertex
  EXPECT_EQ(j["rest"]["positions_mm"].size() % 3, 0u);
  // A session never driven leaves no record.
  auto idle = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(sessions_->Stop(static_cast<uint64_t>(idle->record.id), "not used").ok());
  EXPECT_EQ(store_->GetSessionTrace(idle->record.id).error().code, ErrorCode::kNotFound);
}

TEST_F(SessionManagerTest, CreatedStartedRunningStalledResumedDisconnected) {
  auto s = sessions_->Create("tina", "sphere-palpation-256");  // (none) → created
  ASSERT_TRUE(s.ok()) << s.error().message;
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  EXPECT_EQ(sessions_->Get(id)->state, SessionState::kCreated);
  EXPECT_EQ(store_->GetSession(s->record.id)->state, SessionState::kCreated);
  auto started = sessions_->Start(id);  // created → running
  ASSERT_TRUE(started.ok());
  EXPECT_EQ(started->state, SessionState::kRunning);
  EXPECT_EQ(store_->GetSession(s->record.id)->state, SessionState::kRunning);
  EXPECT_GT(store_->GetSession(s->record.id)->started_us, 0);
  EXPECT_EQ(sessions_->Start(id)->state, SessionState::kRunning) << "Start is idempotent";
  Drive(*s, 1);
  Quiet(0.6);  // running → stalled
  EXPECT_EQ(WaitFor(id, SessionState::kStalled), SessionState::kStalled);
  Drive(*s, 2);  // stalled → running
  EXPECT_EQ(WaitFor(id, SessionState::kRunning), SessionState::kRunning);
  Quiet(0.6);
  EXPECT_EQ(WaitFor(id, SessionState::kStalled), SessionState::kStalled);
  Quiet(5.0);  // stalled → disconnected: no longer live, metrics recorded
  EXPECT_EQ(WaitFor(id, SessionState::kDisconnected), SessionState::kDisconnected);
  EXPECT_FALSE(sessions_->IsLive(id));
  const auto row = store_->GetSession(s->record.id);
  EXPECT_EQ(row->state, SessionState::kDisconnected);
  EXPECT_EQ(row->end_reason, "no stylus data for 5 s");
  EXPECT_TRUE(store_->GetTrialMetrics(s->record.id)->has_value());
  // An ended session cannot start again; stopping it is idempotent and keeps its state.
  EXPECT_EQ(sessions_->Start(id).error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ(sessions_->Stop(id, "")->state, SessionState::kDisconnected);
}

// The haptic rate instructors see is the station's loop, from its own stamps: datagrams that
// arrive in bursts (here: as fast as loopback answers, 3 s of a 1 kHz station in a fraction of a
// second of real time, with a manager clock that does not move) read 1000 Hz, not the burst's
// arrival rate; a 500 Hz station reads 500; a stalled session reads 0. Counting arrivals per
// sampler window on the server's clock read 0 here, and 898–1111 Hz for a steady station.
TEST_F(SessionManagerTest, TheHapticRateIsTheStationsLoopRateNotTheArrivalRate) {
  std::mutex m;
  double rate = -1;
  uint64_t samples = 0, ticks = 0;
  auto s = sessions_->Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(s.ok()) << s.error().message;
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  ASSERT_TRUE(sessions_->Start(id).ok());
  const uint64_t token =
      sessions_->Subscribe(id, [&](const std::vector<SessionTelemetry>& all, bool) {
        std::lock_guard lock(m);
        ++ticks;
        if (!all.empty()) rate = all[0].haptic_rate_hz, samples = all[0].sim.samples;
      });
  // The sampler runs on real time (its own thread, no clock to step): wait for what it shows,
  // polled under the lock, with a 10 s bound. Returns whether `shown` came true.
  auto wait_until = [&](auto shown) {
    return test::Eventually(10, [&] {
      std::lock_guard lock(m);
      return shown();
    });
  };
  // The rate the sampler shows once it has seen the last of `n` samples (the simulation publishes
  // its telemetry every 8th). The rate is measured over windows of at least 1 s of the station's
  // stamps, closed on the sampler's real-time ticks; stamps run ~20× faster than real time here,
  // so the window that spans a change of rate can be long: wait until a window after the change
  // shows `expected`.
  auto rate_after = [&](uint64_t n, double expected) {
    wait_until([&] { return samples + 8 > n && std::abs(rate - expected) <= 1.0; });
    std::lock_guard lock(m);
    return samples + 8 > n ? rate : -1.0;
  };
  // The endpoint's clock moves with the stamps (its rate limit allows a 4 kHz station); the
  // manager's does not, and real time runs ~20× faster than the stamps.
  uint64_t seq = 0;
  for (int i = 0; i < 3000; ++i) endpoint_clock_.Advance(1e-3), Drive(*s, ++seq);
  EXPECT_NEAR(rate_after(3000, 1000.0), 1000.0, 1.0);
  // The same session's station slows to 500 Hz: its stamps go 2 ms apart. The window open at
  // the change mixes both rates; two sampler ticks after 2 s of the new stamps close it, so the
  // next 2 s are a window of the new rate alone.
  const double t0 = 1e-3 * static_cast<double>(seq);
  for (int i = 1; i <= 1000; ++i) endpoint_clock_.Advance(2e-3), Drive(*s, ++seq, t0 + 2e-3 * i);
  ASSERT_TRUE(wait_until([&] { return samples + 8 > 4000; }));
  const uint64_t tick = [&] {
    std::lock_guard lock(m);
    return ticks;
  }();
  ASSERT_TRUE(wait_until([&] { return ticks >= tick + 2; }));
  for (int i = 1001; i <= 2000; ++i) endpoint_clock_.Advance(2e-3), Drive(*s, ++seq, t0 + 2e-3 * i);
  EXPECT_NEAR(rate_after(5000, 500.0), 500.0, 1.0);
  Quiet(0.6);  // running → stalled
  EXPECT_EQ(WaitFor(id, SessionState::kStalled), SessionState::kStalled);
  Drive(*s, ++seq, t0 + 4.5);  // the station is back
  EXPECT_EQ(WaitFor(id, SessionState::kRunning), SessionState::kRunning);
  Quiet(0.6);
  EXPECT_EQ(WaitFor(id, SessionState::kStalled), SessionState::kStalled);
  // The sampler shows the stall on its next tick.
  EXPECT_TRUE(wait_until([&] { return rate == 0.0; })) << rate;
  sessions_->Unsubscribe(token);
}

TEST_F(SessionManagerTest, StopEndsACreatedOrRunningSession) {
  auto created = sessions_->Create("tina", "arm-torsion");
  auto running = sessions_->Create("tina", "arm-torsion");
  ASSERT_TRUE(created.ok() && running.ok());
  const uint64_t a = static_cast<uint64_t>(created->record.id);
  const uint64_t b = static_cast<uint64_t>(running->record.id);
  ASSERT_TRUE(sessions_->Start(b).ok());
  Drive(*running, 1);
  for (uint64_t id : {a, b}) {  // created → ended, running → ended
    auto r = sessions_->Stop(id, "done");
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->state, SessionState::kEnded);
    EXPECT_EQ(r->end_reason, "done");
    EXPECT_FALSE(sessions_->IsLive(id));
    EXPECT_TRUE(store_->GetTrialMetrics(static_cast<int64_t>(id))->has_value());
  }
  // The running one left the endpoint: its key is no longer answered.
  EXPECT_EQ(endpoint_->counters().Dropped(wire::DropReason::kUnknownSession), 0u);
  socket_.non_blocking(true);
  wire::StylusMessage m;
  std::array<uint8_t, wire::kMaxDatagram> buf{};
  const size_t n =
      codec_.EncodeStylus(m, {wire::kProtocolVersion, wire::PayloadType::kStylusState, b, 2},
                          wire::Authenticator(running->key), buf);
  socket_.send_to(asio::buffer(buf.data(), n), udp::endpoint(loopback_, running->udp_port));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (endpoint_->counters().Dropped(wire::DropReason::kUnknownSession) == 0 &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::yield();
  EXPECT_EQ(endpoint_->counters().Dropped(wire::DropReason::kUnknownSession), 1u);
}

// A station's Start and an instructor's Stop that arrive together: whichever wins, the
// session ends with no channel left in the endpoint (a channel opened after the End removed
// them would point at the freed simulation). Every ended session's datagram is then refused
// as unknown, none answered.
TEST_F(SessionManagerTest, AStartRacingAStopLeavesNoChannelBehind) {
  constexpr int kRounds = 40;
  std::vector<CreatedSession> ended;
  for (int round = 0; round < kRounds; ++round) {
    auto s = sessions_->Create("tina", "arm-torsion");
    ASSERT_TRUE(s.ok()) << s.error().message;
    const uint64_t id = static_cast<uint64_t>(s->record.id);
    std::atomic<bool> go{false};
    std::thread starter([&] {
      while (!go.load()) std::this_thread::yield();
      (void)sessions_->Start(id);  // refused when the Stop came first: that is fine
    });
    go.store(true);
    if (round % 2 == 1) std::this_thread::yield();  // either order, both tried
    ASSERT_TRUE(sessions_->Stop(id, "raced").ok());
    starter.join();
    ASSERT_FALSE(sessions_->IsLive(id));
    ended.push_back(*s);
  }
  socket_.non_blocking(true);
  for (const CreatedSession& s : ended) {
    wire::StylusMessage m;
    m.sample.position = Eigen::Vector3d(0, 0, 0.2);
    std::array<uint8_t, wire::kMaxDatagram> buf{};
    const uint64_t id = static_cast<uint64_t>(s.record.id);
    const size_t n =
        codec_.EncodeStylus(m, {wire::kProtocolVersion, wire::PayloadType::kStylusState, id, 1},
                            wire::Authenticator(s.key), buf);
    socket_.send_to(asio::buffer(buf.data(), n), udp::endpoint(loopback_, s.udp_port));
  }
  const auto unknown = [&] {
    return endpoint_->counters().Dropped(wire::DropReason::kUnknownSession);
  };
  EXPECT_TRUE(test::Eventually(10, [&] { return unknown() >= kRounds; }));
  EXPECT_EQ(unknown(), static_cast<uint64_t>(kRounds));
  std::array<uint8_t, 2048> in{};
  udp::endpoint from;
  boost::system::error_code ec;
  socket_.receive_from(asio::buffer(in), from, 0, ec);
  EXPECT_EQ(ec, asio::error::would_block) << "an ended session's datagram was answered";
}

TEST_F(SessionManagerTest, ASessionNeverStartedExpiresAsAborted) {
  auto s = sessions_->Create("tina", "arm-torsion");
  ASSERT_TRUE(s.ok());
  const uint64_t id = static_cast<uint64_t>(s->record.id);
  clock_.Advance(59.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // several sampler ticks
  EXPECT_EQ(sessions_->Get(id)->state, SessionState::kCreated) << "not yet 60 s";
  clock_.Advance(2.0);  // created → aborted
  EXPECT_EQ(WaitFor(id, SessionState::kAborted), SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(s->record.id)->end_reason, "not started within 60 s");
}

TEST_F(SessionManagerTest, LosingAccessOrAShutdownAbortsEveryLiveSession) {
  auto mine = sessions_->Create("tina", "arm-torsion");
  auto other = sessions_->Create("tom", "arm-torsion");
  ASSERT_TRUE(mine.ok() && other.ok());
  ASSERT_TRUE(sessions_->Start(static_cast<uint64_t>(mine->record.id)).ok());
  // The limit: a third live session for tina is refused, and counts nothing.
  ASSERT_TRUE(sessions_->Create("tina", "arm-torsion").ok());
  EXPECT_EQ(sessions_->Create("tina", "arm-torsion").error().code, ErrorCode::kResourceExhausted);
  EXPECT_EQ(sessions_->EndSessionsOf("tina", "access revoked"), 2);  // live → aborted
  EXPECT_EQ(store_->GetSession(mine->record.id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(mine->record.id)->end_reason, "access revoked");
  EXPECT_TRUE(sessions_->IsLive(static_cast<uint64_t>(other->record.id)));
  sessions_->Shutdown();  // live → aborted
  EXPECT_EQ(store_->GetSession(other->record.id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(other->record.id)->end_reason, "server shut down");
  EXPECT_TRUE(store_->GetTrialMetrics(other->record.id)->has_value());
}

TEST_F(SessionManagerTest, WhatAKilledServerLeftLiveIsAbortedAtStartUp) {
  auto s = sessions_->Create("tina", "arm-torsion");
  ASSERT_TRUE(s.ok());
  // A second manager on the same store stands for the next process after a crash.
  auto next = SessionManager::Open(*store_, nullptr, {});
  ASSERT_TRUE(next.ok()) << next.error().message;
  EXPECT_EQ(store_->GetSession(s->record.id)->state, SessionState::kAborted);
  EXPECT_EQ(store_->GetSession(s->record.id)->end_reason, "server restarted");
}

// Settings → object, validated once: each bad field is named, nothing is written and no thread
// starts; a simulation node's manager needs its lease.
TEST_F(SessionManagerTest, BadOptionsAreRefusedByNameBeforeAnythingStarts) {
  auto s = sessions_->Create("tina", "arm-torsion");
  ASSERT_TRUE(s.ok());
  auto with = [](auto change) {
    SessionManagerOptions o;
    change(o);
    return o;
  };
  const std::pair<SessionManagerOptions, const char*> bad[] = {
      {with([](auto& o) { o.udp_host = ""; }), "udp_host"},
      {with([](auto& o) { o.telemetry_hz = 0; }), "telemetry_hz"},
      {with([](auto& o) { o.telemetry_hz = NAN; }), "telemetry_hz"},
      {with([](auto& o) { o.max_live_sessions = 0; }), "max_live_sessions"},
      {with([](auto& o) { o.max_sessions_per_user = 0; }), "max_sessions_per_user"},
      {with([](auto& o) { o.start_timeout_s = -1; }), "start_timeout_s"},
      {with([](auto& o) { o.node = "sim-0"; }), "lease"},
  };
  for (const auto& [options, field] : bad) {
    auto m = SessionManager::Open(*store_, nullptr, options);
    ASSERT_FALSE(m.ok()) << field;
    EXPECT_EQ(m.error().code, ErrorCode::kInvalidArgument) << field;
    EXPECT_EQ(m.error().field, field);
  }
  EXPECT_EQ(store_->GetSession(s->record.id)->state, SessionState::kCreated)
      << "a refused manager aborted the live session";
}

}  // namespace
}  // namespace vsurg::server
