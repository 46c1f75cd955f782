// Placement over a site's nodes: spread, capacity, bursts, drain, live migration of a draining
// node's sessions, and an instructor's join reaching the session's node.
#include "tests/server/cluster/cluster_fixture.h"

namespace vsurg::server::cluster {
namespace {

using namespace test_cluster;  // NOLINT: the suites' fixture and helpers

TEST_F(ClusterTest, PlacementSpreadsFillsToCapacityAndTellsTheNodesAddress) {
  AddNode("sim-a", 3);
  AddNode("sim-b", 3);
  WaitForNodes(2);
  for (int i = 0; i < 6; ++i) {
    auto c = control_->Create("trainee-" + std::to_string(i), "arm-torsion");
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(c->udp_host, "127.0.0.1");
    EXPECT_EQ(c->udp_port, nodes_[c->record.node == "sim-a" ? 0 : 1]->endpoint->port());
    EXPECT_EQ(control_store_->GetSession(c->record.id)->node, c->record.node);
    auto counts = PerNode();
    EXPECT_LE(std::abs(counts["sim-a"] - counts["sim-b"]), 1) << "after " << i + 1;
  }
  // Both full: refused with a reason, nothing created.
  auto full = control_->Create("trainee-9", "arm-torsion");
  ASSERT_FALSE(full.ok());
  EXPECT_EQ(full.error().code, ErrorCode::kUnavailable);
  EXPECT_NE(full.error().message.find("no simulation node has room"), std::string::npos);
  // The session's calls go to its node: join gives the same key, stop ends it there.
  auto first = control_store_->ListSessions(std::string("trainee-0")).value().at(0);
  auto joined = control_->Join(static_cast<uint64_t>(first.id), false);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  EXPECT_FALSE(joined->surface) << "a probe's join carries no surface";
  // A twist scene sends no surface for the station (HapticsSpec::StationSurface); a press scene
  // does, from its node through the control plane, with its creation and a join that asks
  // (below).
  EXPECT_FALSE(control_->Join(static_cast<uint64_t>(first.id), true)->surface);
  auto stopped = control_->Stop(static_cast<uint64_t>(first.id), "done");
  ASSERT_TRUE(stopped.ok()) << stopped.error().message;
  EXPECT_EQ(stopped->state, SessionState::kEnded);
  EXPECT_FALSE(control_->IsLive(static_cast<uint64_t>(first.id)));
  // A scene that does not exist is the request's fault, not a node's: no other node is tried.
  auto bad = control_->Create("trainee-10", "no-such-scene");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, ErrorCode::kNotFound);
  // The scrape: the placements per node, the refusals (no room; the scene that does not exist),
  // the registry (five live sessions: six placed, one stopped); and a node's own lease.
  ops::MetricsText m;
  control_->Collect(m);
  const std::string& text = m.str();
  const auto value = [&](const std::string& series) {
    const size_t at = text.find(series + " ");
    return at == std::string::npos ? -1.0 : std::stod(text.substr(at + series.size() + 1));
  };
  EXPECT_EQ(value("vsurg_placements_total{node=\"sim-a\"}"), 3) << text;
  EXPECT_EQ(value("vsurg_placements_total{node=\"sim-b\"}"), 3);
  EXPECT_EQ(value("vsurg_placement_refusals_total{reason=\"no_room\"}"), 1);
  EXPECT_EQ(value("vsurg_placement_refusals_total{reason=\"invalid_request\"}"), 1);
  EXPECT_EQ(value("vsurg_placement_refusals_total{reason=\"node_failed\"}"), 0);
  EXPECT_EQ(value("vsurg_placement_refusals_total{reason=\"trainee_limit\"}"), 0);
  EXPECT_EQ(value("vsurg_nodes{state=\"up\"}"), 2);
  EXPECT_EQ(value("vsurg_node_live_sessions{node=\"sim-a\"}") +
                value("vsurg_node_live_sessions{node=\"sim-b\"}"),
            5);
  EXPECT_EQ(value("vsurg_node_capacity{node=\"sim-b\"}"), 3);
  EXPECT_EQ(value("vsurg_node_epoch{node=\"sim-a\"}"), 1);
  EXPECT_GE(value("vsurg_node_lease_age_seconds{node=\"sim-b\"}"), 0);
  ops::MetricsText n;
  nodes_[0]->agent->Collect(n);
  EXPECT_NE(n.str().find("vsurg_lease_held 1\n"), std::string::npos) << n.str();
  EXPECT_NE(n.str().find("vsurg_lease_epoch 1\n"), std::string::npos) << n.str();
  EXPECT_EQ(n.str().find("vsurg_lease_seconds_left -"), std::string::npos) << n.str();
  // (after the scrape: one more placement)
  auto press = control_->Create("trainee-0", "sphere-palpation-256");
  ASSERT_TRUE(press.ok()) << press.error().message;
  ASSERT_TRUE(press->surface);
  EXPECT_GT(press->surface->spec().tissue_stiffness, 0) << "the scene's tissue law";
  auto rejoined = control_->Join(press->record.id, true);
  ASSERT_TRUE(rejoined.ok() && rejoined->surface);
  EXPECT_EQ(rejoined->surface->spec().positions.size(), press->surface->spec().positions.size());
  EXPECT_FALSE(control_->Join(press->record.id, false)->surface);
  ASSERT_TRUE(control_->Stop(press->record.id, "done").ok());
}

// A burst of stations at once (a class starting together): each placement sees the ones still
// in flight, so the nodes end within one session of each other, not piled onto the first.
TEST_F(ClusterTest, ABurstOfConcurrentPlacementsStaysBalanced) {
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  AddNode("sim-c", 8);
  WaitForNodes(3);
  constexpr int kSessions = 15;
  std::vector<std::thread> threads;
  std::atomic<int> failed{0};
  for (int i = 0; i < kSessions; ++i)
    threads.emplace_back([&, i] {
      if (!control_->Create("trainee-" + std::to_string(i), "arm-torsion").ok()) ++failed;
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(failed.load(), 0);
  auto counts = PerNode();
  int lo = kSessions, hi = 0, total = 0;
  for (const char* name : {"sim-a", "sim-b", "sim-c"}) {
    lo = std::min(lo, counts[name]);
    hi = std::max(hi, counts[name]);
    total += counts[name];
  }
  EXPECT_EQ(total, kSessions);
  EXPECT_LE(hi - lo, 1) << "sim-a=" << counts["sim-a"] << " sim-b=" << counts["sim-b"]
                        << " sim-c=" << counts["sim-c"];
}

// Two control replicas placing a class at once (a site's stations fail over between them): each
// placement reserves its node in the store before it asks the node, so neither replica takes the
// other's placements in flight for its own or misses them, and the nodes end within one session
// of each other. (Each replica counting only its own in flight, the first's 16 went 6, 5, 5 and
// the second's 8 went 3, 3, 2: 9, 8, 7.)
TEST_F(ClusterTest, TwoReplicasPlacingAtOnceStayBalanced) {
  AddNode("sim-a", 12);
  AddNode("sim-b", 12);
  AddNode("sim-c", 12);
  WaitForNodes(3);
  auto second = SecondReplica();
  ASSERT_TRUE(second);
  constexpr int kSessions = 24;
  std::vector<std::thread> threads;
  std::atomic<int> failed{0};
  for (int i = 0; i < kSessions; ++i)
    threads.emplace_back([&, i] {
      ClusterSessions& via = i % 3 == 2 ? *second : *control_;
      if (!via.Create("trainee-" + std::to_string(i), "arm-torsion").ok()) ++failed;
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(failed.load(), 0);
  auto counts = PerNode();
  EXPECT_EQ(counts["sim-a"] + counts["sim-b"] + counts["sim-c"], kSessions);
  const auto [lo, hi] = std::minmax({counts["sim-a"], counts["sim-b"], counts["sim-c"]});
  EXPECT_LE(hi - lo, 1) << "sim-a=" << counts["sim-a"] << " sim-b=" << counts["sim-b"]
                        << " sim-c=" << counts["sim-c"];
  EXPECT_EQ(Metric(*control_, "vsurg_placements_in_flight"), -1) << "none left in flight";
  second->Shutdown();
}

// --drain-wait: the live sessions finish where they are.
TEST_F(ClusterTest, ADrainingNodeTakesNoNewSessionsAndItsLiveOnesFinish) {
  migrate_ = false;
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  WaitForNodes(2);
  auto on_a = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(on_a.ok());
  const std::string drained = on_a->record.node, other = drained == "sim-a" ? "sim-b" : "sim-a";
  Node& a = NodeNamed(drained);
  std::jthread drain([&] { a.agent->Drain(10); });  // joined however the test ends
  auto draining = [&] {
    const auto nodes = control_store_->ListNodes();  // kept: the loop reads into it
    for (const auto& n : nodes.value())
      if (n.name == drained) return n.draining;
    return false;
  };
  ASSERT_TRUE(test::Eventually(10, draining));
  for (int i = 1; i <= 3; ++i) {  // the other node has 0, 1, 2: the draining one would be next
    auto c = control_->Create("trainee-" + std::to_string(i), "arm-torsion");
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(c->record.node, other);
  }
  EXPECT_TRUE(control_->IsLive(on_a->record.id));  // the live one goes on
  ASSERT_TRUE(control_->Stop(on_a->record.id, "finished").ok());
  drain.join();  // returns once sim-a has no live session
  EXPECT_EQ(a.sessions->LiveCount(), 0);
}

// A station over raw UDP for one session (the test's): sends a stylus sample and reads the
// answers that came back.
class UdpStation {
 public:
  UdpStation(uint64_t session, const wire::SessionKey& key, uint16_t port)
      : session_(session), port_(port), auth_(key) {
    sock_.non_blocking(true);
  }
  void Target(uint16_t port) { port_ = port; }
  // At most 2 kHz (the endpoint's rate limit is 4 kHz per session).
  uint64_t Send(const haptics::StylusSample& s) {
    std::this_thread::sleep_until(next_);
    next_ = std::chrono::steady_clock::now() + std::chrono::microseconds(500);
    wire::StylusMessage m;
    m.sample = s;
    std::vector<uint8_t> buf(wire::kMaxDatagram);
    const size_t n = codec_.EncodeStylus(
        m, {wire::kProtocolVersion, wire::PayloadType::kStylusState, session_, ++seq_}, auth_, buf);
    sock_.send_to(boost::asio::buffer(buf.data(), n),
                  {boost::asio::ip::make_address("127.0.0.1"), port_});
    return seq_;
  }
  // The answer to sequence `seq` (earlier ones are skipped), waiting up to `seconds`.
  std::optional<wire::ForceMessage> AnswerTo(uint64_t seq, double seconds) {
    std::optional<wire::ForceMessage> got;
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    std::vector<uint8_t> buf(wire::kMaxDatagram);
    const auto poll = [&] {
      boost::asio::ip::udp::endpoint from;
      boost::system::error_code ec;
      for (;;) {
        const size_t n = sock_.receive_from(boost::asio::buffer(buf), from, 0, ec);
        if (ec) break;
        wire::Opened o;
        if (wire::Open(std::span<const uint8_t>(buf.data(), n), &auth_, o) !=
                wire::DropReason::kNone ||
            o.header.type != wire::PayloadType::kForceFeedback)
          continue;
        wire::ForceMessage f;
        if (codec_.DecodeForce(o.payload, f) == wire::DropReason::kNone && f.echo_sequence == seq)
          got = f;
      }
      return got.has_value();
    };
    while (!poll() && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    return got;
  }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::udp::socket sock_{io_, boost::asio::ip::udp::v4()};
  wire::Codec codec_;
  uint64_t session_;
  uint16_t port_;
  wire::Authenticator auth_;
  uint64_t seq_ = 0;
  std::chrono::steady_clock::time_point next_ = std::chrono::steady_clock::now();
};

// Live migration. A node drains with a trainee mid-twist and a session not yet started: both go
// to the other node with their whole state. The old node answers the trainee's station only with
// a notice that the session moved;
// asked where the session runs (Join, as the station's probe does), the site names the other
// node and the same key; there the twist goes on with the force it had (not a start-up ramp from
// zero), and the trial ends with one record covering the whole trial: the path and the time before
// the move included, the record's series from the start.
TEST_F(ClusterTest, ADrainingNodeMovesItsLiveSessionsWithTheirStateAndTheTrialGoesOn) {
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  auto live = control_->Create("trainee-0", "arm-torsion");
  auto waiting = control_->Create("trainee-1", "arm-torsion");
  ASSERT_TRUE(live.ok() && waiting.ok());
  ASSERT_EQ(live->record.node, "sim-a");
  ASSERT_EQ(waiting->record.node, "sim-a");
  Node& b = AddNode("sim-b", 8);
  WaitForNodes(2);
  ASSERT_TRUE(control_->Start(live->record.id).ok());

  auto scene = sim::LoadSceneByName("arm-torsion");
  ASSERT_TRUE(scene.ok());
  auto samples = sim::ScriptedTrainee(*scene, sim::TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  UdpStation station(live->record.id, live->key, a.endpoint->port());
  // Lockstep up to 0.3 s into the grasp: each sample answered before the next goes.
  size_t k = 0, grasped_at = 0;
  wire::ForceMessage before;
  for (; k < samples->size(); ++k) {
    const auto f = station.AnswerTo(station.Send((*samples)[k]), 5);
    ASSERT_TRUE(f) << "sample " << k << " unanswered before the move";
    before = *f;
    if (before.command.grasping && grasped_at == 0) grasped_at = k;
    if (grasped_at > 0 && k >= grasped_at + 300) break;
  }
  ASSERT_GT(grasped_at, 0u) << "the trainee never grasped";
  ASSERT_TRUE(before.command.grasping);
  ASSERT_GT(before.command.force.norm(), 0.05);
  ++k;

  EXPECT_EQ(a.agent->Drain(10), 2);
  EXPECT_EQ(a.sessions->LiveCount(), 0);
  for (const auto* s : {&*live, &*waiting}) {
    auto row = control_store_->GetSession(s->record.id);
    ASSERT_TRUE(row.ok());
    EXPECT_EQ(row->node, "sim-b");
    EXPECT_TRUE(b.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  }
  // Live on its new node: running, or stalled when 0.5 s passed without a sample (the station
  // here sends nothing during the drain; an instrumented build's migration takes that long).
  const SessionState moved_state = control_->Get(live->record.id)->state;
  EXPECT_TRUE(moved_state == SessionState::kRunning || moved_state == SessionState::kStalled)
      << static_cast<int>(moved_state);
  EXPECT_EQ(control_->Get(waiting->record.id)->state, SessionState::kCreated);
  // The session that was waiting starts on its new node (now: a session not started within 60 s
  // of its creation is aborted, and the rest of this test replays a whole trial).
  auto started = control_->Start(waiting->record.id);
  ASSERT_TRUE(started.ok()) << started.error().message;
  EXPECT_EQ(started->state, SessionState::kRunning);
  // The old node answers the station only to say that the session moved: no force.
  const auto notice = station.AnswerTo(station.Send((*samples)[k]), 5);
  ASSERT_TRUE(notice) << "the old node said nothing";
  EXPECT_NE(notice->command.events & haptics::kEventSessionMoved, 0u);
  EXPECT_EQ(notice->command.force.norm(), 0);
  EXPECT_FALSE(notice->command.grasping);
  // Where it runs now: the other node, the same key.
  auto joined = control_->Join(live->record.id, true);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  EXPECT_EQ(joined->record.node, "sim-b");
  EXPECT_EQ(joined->udp_port, b.endpoint->port());
  EXPECT_EQ(joined->key, live->key);
  station.Target(joined->udp_port);
  const auto after = station.AnswerTo(station.Send((*samples)[k]), 5);
  ASSERT_TRUE(after) << "the new node does not answer";
  EXPECT_TRUE(after->command.grasping) << "the grasp was let go by the move";
  // The twist goes on: the force within a tenth of what it was one sample (1 ms) before, and not
  // gated to zero by a fresh safety filter's start-up ramp.
  EXPECT_NEAR(after->command.force.norm(), before.command.force.norm(),
              0.1 * before.command.force.norm() + 0.02);
  for (++k; k < samples->size(); ++k)
    ASSERT_TRUE(station.AnswerTo(station.Send((*samples)[k]), 5)) << "sample " << k;

  auto stopped = control_->Stop(live->record.id, "done");
  ASSERT_TRUE(stopped.ok()) << stopped.error().message;
  EXPECT_EQ(stopped->state, SessionState::kEnded);
  // One trial, the whole of it: the same path and duration as the trial played offline.
  sim::SimulationOptions offline;
  offline.threaded = false;
  auto reference = sim::Simulation::Create(*scene, offline);
  ASSERT_TRUE(reference.ok());
  std::vector<haptics::StylusSample> played(samples->begin(), samples->end());
  played.insert(played.begin() + static_cast<std::ptrdiff_t>(grasped_at + 301),
                (*samples)[grasped_at + 301]);  // the sample the old node answered with a notice
  (*reference)->Replay(played, {});
  const scoring::TrialMetrics want = (*reference)->Metrics();
  auto got = control_store_->GetTrialMetrics(live->record.id);
  ASSERT_TRUE(got.ok() && got->has_value());
  EXPECT_NEAR((*got)->duration, want.duration, 1e-6);
  EXPECT_NEAR((*got)->path_length, want.path_length, 1e-6);
  EXPECT_TRUE((*got)->completed);
  auto trace = control_store_->GetSessionTrace(live->record.id);
  ASSERT_TRUE(trace.ok());
  const auto series = nlohmann::json::parse(*trace)["series"]["time_s"];
  ASSERT_FALSE(series.empty());
  EXPECT_LT(series.front().get<double>(), (*samples)[grasped_at].time)
      << "the record lost what the old node recorded";
  EXPECT_EQ(Metric(*control_, "vsurg_migrations_total{outcome=\"moved\"}"), 2);
}

// No other node takes it (the only node drains): the session stays and is served where it was;
// the drain then waits for it as --drain-wait does.
TEST_F(ClusterTest, ASessionNoOtherNodeTakesStaysAndIsServedWhereItWas) {
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok());
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  UdpStation station(s->record.id, s->key, a.endpoint->port());
  haptics::StylusSample free;
  free.position = Eigen::Vector3d(0, 0, 0.3);
  free.time = 0.001;
  ASSERT_TRUE(station.AnswerTo(station.Send(free), 5));
  EXPECT_EQ(a.agent->Drain(0.5), 0);
  EXPECT_TRUE(a.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  EXPECT_EQ(control_store_->GetSession(s->record.id)->node, "sim-a");
  free.time = 0.002;
  EXPECT_TRUE(station.AnswerTo(station.Send(free), 5)) << "not served again after the failed move";
  EXPECT_GE(Metric(*control_, "vsurg_migrations_total{outcome=\"no_room\"}"), 1);
  ASSERT_TRUE(control_->Stop(s->record.id, "done").ok());
  EXPECT_EQ(control_->Get(s->record.id)->state, SessionState::kEnded);
}

// A node's process gone (its gRPC port closed, as after a crash): the first late heartbeat
// finds its port refusing connections, and the node is down without waiting out the timeout.

// Four-handed training on a site: the control replica sends an instructor's join to the node the
// session runs on, which opens the instructor's own channel there; the mode, and who is in the
// session, go and come back through the replica; both stations are answered on the node, the
// guidance reaches the trainee's haptic path, and leaving closes the instructor's channel.
TEST_F(ClusterTest, AnInstructorJoinsASessionOnItsNodeThroughTheControlPlane) {
  Node& a = AddNode("sim-a", 4);
  Node& b = AddNode("sim-b", 4);
  WaitForNodes(2);
  auto created = control_->Create("trainee-0", "sphere-palpation-256");
  ASSERT_TRUE(created.ok()) << created.error().message;
  const uint64_t id = created->record.id;
  ASSERT_TRUE(control_->Start(id).ok());
  const Node& at = created->record.node == "sim-a" ? a : b;

  auto joined = control_->JoinInstructor(id, "instructor-0");
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  EXPECT_EQ(joined->channel, InstructorChannel(id));
  EXPECT_EQ(joined->record.node, created->record.node);
  EXPECT_EQ(joined->udp_port, at.endpoint->port());
  EXPECT_NE(joined->key, created->key);
  EXPECT_EQ(control_->JoinInstructor(id, "instructor-1").error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(control_->Guide(id, "instructor-1", {sim::GuideMode::kGuide, 0.5}).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(control_->Guide(id, "instructor-0", {sim::GuideMode::kGuide, 1.5}).error().code,
            ErrorCode::kInvalidArgument);
  auto g = control_->Guide(id, "instructor-0", {sim::GuideMode::kGuide, 0.5});
  ASSERT_TRUE(g.ok()) << g.error().message;
  EXPECT_EQ(g->trainee, "trainee-0");
  EXPECT_EQ(g->instructor, "instructor-0");
  EXPECT_EQ(g->requested.mode, sim::GuideMode::kGuide);
  EXPECT_DOUBLE_EQ(g->requested.alpha, 0.5);

  // Both hands press the sphere, each station on its own channel to the node; the dominance
  // ramps on the node's haptic path while the instructor's samples are fresh.
  UdpStation trainee(id, created->key, created->udp_port);
  UdpStation instructor(joined->channel, joined->key, joined->udp_port);
  const auto press = test::PressAndHold(8.0);
  size_t answered_trainee = 0, answered_instructor = 0;
  double alpha_now = 0;
  for (size_t k = 0; k < press.size() && alpha_now <= 0.45; ++k) {
    haptics::StylusSample s = press[k];
    s.time = 1e-3 * static_cast<double>(k);
    answered_trainee += trainee.AnswerTo(trainee.Send(s), 5).has_value();
    answered_instructor += instructor.AnswerTo(instructor.Send(s), 5).has_value();
    if (k % 50 == 49) alpha_now = control_->Guidance(id).value().alpha;
  }
  EXPECT_GT(alpha_now, 0.45);
  EXPECT_GT(answered_trainee, 0u);
  EXPECT_GT(answered_instructor, 0u);

  // Leaving hands the tool back and closes the instructor's channel on the node.
  ASSERT_TRUE(control_->LeaveInstructor(id, "instructor-0").ok());
  EXPECT_EQ(control_->Guidance(id).value().instructor, "");
  EXPECT_FALSE(instructor.AnswerTo(instructor.Send(press.back()), 0.3).has_value());
  EXPECT_TRUE(trainee.AnswerTo(trainee.Send(press.back()), 5).has_value());
  EXPECT_EQ(control_->LeaveInstructor(id, "instructor-0").error().code,
            ErrorCode::kFailedPrecondition);
  ASSERT_TRUE(control_->Stop(id, "done").ok());
  EXPECT_EQ(control_->JoinInstructor(id, "instructor-0").error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace vsurg::server::cluster
