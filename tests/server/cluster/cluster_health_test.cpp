// A site's nodes failing: refused ports, silence, frozen processes, and the telemetry and
// heartbeats the control plane keeps in memory.
#include "tests/server/cluster/cluster_fixture.h"

namespace vsurg::server::cluster {
namespace {

using namespace test_cluster;  // NOLINT: the suites' fixture and helpers

TEST_F(ClusterTest, ANodeWhosePortRefusesIsMarkedDownAndItsSessionsAborted) {
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  WaitForNodes(2);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok());
  const std::string gone = s->record.node, other = gone == "sim-a" ? "sim-b" : "sim-a";
  NodeNamed(gone).agent->Shutdown();  // its heartbeats stop and its port closes
  EXPECT_TRUE(test::Eventually(options_.heartbeat_timeout_s + 10,
                               [&] { return !control_->IsLive(s->record.id); }));
  auto row = control_->Get(s->record.id);
  ASSERT_TRUE(row.ok());
  EXPECT_EQ(row->state, SessionState::kAborted);
  // Decided by the refusal, not by the timeout.
  EXPECT_NE(row->end_reason.find(gone + " stopped answering (its port refuses connections)"),
            std::string::npos)
      << row->end_reason;
  // New sessions go to the node that answers.
  auto next = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(next.ok()) << next.error().message;
  EXPECT_EQ(next->record.node, other);
}

// A node that is silent while its port still takes connections (a machine stopped, a process
// frozen: the kernel completes the handshake) may come back: it is probed, and down only after
// the 2 s timeout.
TEST_F(ClusterTest, ASilentNodeWhosePortStillAcceptsIsDownOnlyAfterTheTimeout) {
  FrozenNode frozen;
  ASSERT_TRUE(frozen.ok());
  const auto t0 = std::chrono::steady_clock::now();  // the beat is stamped after this
  const v1::NodeLeaseReply reply = frozen.Acquire(control_->port(), "sim-frozen", 8);
  EXPECT_EQ(reply.epoch(), 1);
  EXPECT_EQ(reply.lease_s(), options_.heartbeat_timeout_s);
  WaitForNodes(1);
  const auto down = [&] { return control_store_->ListNodes().value().at(0).down; };
  test::Eventually(options_.heartbeat_timeout_s + 5, down, std::chrono::milliseconds(20));
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(down());
  EXPECT_GE(waited, options_.heartbeat_timeout_s - 0.05)
      << "not before the heartbeat timeout after the last beat";
  // It was probed meanwhile (a connection waits in the listen queue), and that kept it up.
  EXPECT_TRUE(frozen.Called()) << "the control plane never probed the late node";
}

// The control plane's gRPC API in front of a replica whose node is frozen: trainees' Creates wait
// on it (it never builds their scenes), and a station's Join of a session there waits too. On a
// two-core machine gRPC ran every handler on two threads of its own, so two such calls stalled
// every other call on the replica for up to the node-call timeout (the site's e2e test: stations
// of a killed node could not even read that their session was aborted). Calls now run on threads
// that may wait, and a node call made for a caller ends with that caller's deadline.
class ClusterFrozenNodeTest : public ClusterTest {
 protected:
  void Configure() override {
    // The node stays "up" for the whole test (it is probed, its port accepts) and each node call
    // would wait a minute: what the test sees comes from the calls, not from a timeout.
    options_.heartbeat_timeout_s = 60;
    options_.store_lease_s = 120;
    options_.call_timeout_s = 60;
    options_.create_timeout_s = 60;
    options_.max_sessions_per_user = 2;
  }
};

TEST_F(ClusterFrozenNodeTest, CallsWaitingOnAFrozenNodeStallNoOtherCallAndEndWithTheirCaller) {
  FrozenNode frozen(/*handshake=*/true);
  ASSERT_TRUE(frozen.ok());
  const int64_t epoch = frozen.Acquire(control_->port(), "sim-frozen", 64).epoch();
  WaitForNodes(1);
  auto cp = ControlPlane::Start(*control_store_, *control_, {});
  ASSERT_TRUE(cp.ok()) << cp.error().message;
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string((*cp)->port()),
                                     grpc::InsecureChannelCredentials());
  auto stub = v1::SessionService::NewStub(channel);
  std::map<std::string, std::string> tokens;
  for (int i = 0; i <= 10; ++i) {
    const std::string name = "trainee-" + std::to_string(i);
    ASSERT_TRUE(control_store_->CreateUser(name, db::Role::kTrainee, "group-a").ok());
    tokens[name] = control_store_->IssueToken(name, "test").value();
  }
  const auto ctx = [&](const std::string& who, double seconds) {
    auto c = std::make_unique<grpc::ClientContext>();
    c->AddMetadata("authorization", "Bearer " + tokens[who]);
    c->set_deadline(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(static_cast<int>(seconds * 1000)));
    return c;
  };

  // Twenty Creates, more than gRPC's callback threads on any machine (at most 16), all placed on
  // the frozen node: each waits for it to build the scene.
  std::vector<std::future<grpc::Status>> creates;
  std::atomic<int> sent{0};
  for (int i = 0; i < 20; ++i)
    creates.push_back(std::async(std::launch::async, [&, i] {
      v1::CreateSessionRequest req;
      req.set_scene("arm-torsion");
      v1::CreateSessionResponse resp;
      auto c = ctx("trainee-" + std::to_string(i / 2), 90);
      ++sent;
      return stub->Create(c.get(), req, &resp);
    }));
  // All twenty wait on the node at once: none waits for a thread behind another.
  ASSERT_TRUE(test::Eventually(30,
                               [&] {
                                 return sent == 20 && frozen.Called() &&
                                        Metric(*control_, "vsurg_placements_in_flight") == 20;
                               }))
      << Metric(*control_, "vsurg_placements_in_flight") << " Creates wait on the node";

  // Meanwhile another trainee's calls are answered.
  v1::ListScenesResponse scenes;
  const grpc::Status listed =
      stub->ListScenes(ctx("trainee-10", 30).get(), v1::ListScenesRequest{}, &scenes);
  ASSERT_TRUE(listed.ok()) << listed.error_message();
  EXPECT_GT(scenes.scenes_size(), 0);

  // The dashboard likewise: a session created from it waits on the node on a node-call worker,
  // not on the I/O thread that answers everyone.
  HttpServerOptions ho;
  ho.listen = "127.0.0.1:0";
  auto web = HttpServer::Start(*control_store_, *control_, ho);
  ASSERT_TRUE(web.ok()) << web.error().message;
  const int web_port = (*web)->port();
  auto created_on_web = std::async(std::launch::async, [&] {
    return HttpStatus(web_port, "POST", "/api/v1/sessions", tokens["trainee-9"],
                      R"({"scene": "arm-torsion"})", 90);
  });
  ASSERT_TRUE(test::Eventually(30, [&] {
    return Metric(*control_, "vsurg_placements_in_flight") == 21 ||
           created_on_web.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  }));
  EXPECT_EQ(HttpStatus(web_port, "GET", "/api/v1/scenes", tokens["trainee-10"], "", 30), 200);

  // A session of theirs on the frozen node: a station's Join (its 1 s probe) ends with the
  // station's deadline, and the node call made for it with it; a Get still answers.
  auto row = control_store_->CreateSession("trainee-10", "arm-torsion", {"sim-frozen", epoch});
  ASSERT_TRUE(row.ok()) << row.error().message;
  v1::SessionRef ref;
  ref.set_id(static_cast<uint64_t>(row->id));
  v1::CreateSessionResponse joined;
  v1::JoinRequest join;
  join.set_id(ref.id());
  EXPECT_FALSE(stub->Join(ctx("trainee-10", 1).get(), join, &joined).ok());
  v1::Session got;
  const grpc::Status get = stub->Get(ctx("trainee-10", 30).get(), ref, &got);
  ASSERT_TRUE(get.ok()) << get.error_message();
  EXPECT_EQ(got.id(), ref.id());
  {
    const CallerDeadline caller(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
    const auto t0 = std::chrono::steady_clock::now();
    auto direct = control_->Join(ref.id(), false);
    ASSERT_FALSE(direct.ok());
    EXPECT_NE(direct.error().message.find("sim-frozen"), std::string::npos)
        << direct.error().message;
    // Within the caller's deadline, not the node call's minute (a liveness bound, not a timing
    // goal: half the minute).
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
              options_.call_timeout_s / 2);
  }

  // All that while, every Create still waited on the node; its process gone, each ends with an
  // error, none with a session.
  for (auto& c : creates)
    EXPECT_EQ(c.wait_for(std::chrono::seconds(0)), std::future_status::timeout);
  EXPECT_EQ(created_on_web.wait_for(std::chrono::seconds(0)), std::future_status::timeout);
  frozen.Close();
  for (auto& c : creates) {
    ASSERT_EQ(c.wait_for(std::chrono::seconds(60)), std::future_status::ready);
    EXPECT_FALSE(c.get().ok());
  }
  ASSERT_EQ(created_on_web.wait_for(std::chrono::seconds(60)), std::future_status::ready);
  EXPECT_EQ(created_on_web.get(), 503);  // no node has room: it answered nothing
  (*web)->Shutdown();
  cp->reset();
}

// A Create waiting on a node that froze while building the scene (SIGSTOP, a paused VM: it
// accepts connections and never answers) is placed on another node in the same call once the
// site declares the frozen node down, instead of waiting out the create timeout (here two
// minutes) on a node that will never answer; the station that asked gets its session.
TEST_F(ClusterTest, ACreateWaitingOnANodeDeclaredDownIsPlacedOnAnotherInTheSameCall) {
  FrozenNode frozen(/*handshake=*/true);
  ASSERT_TRUE(frozen.ok());
  frozen.Acquire(control_->port(), "sim-frozen", 64);
  WaitForNodes(1);
  auto created =
      std::async(std::launch::async, [&] { return control_->Create("tina", "arm-torsion"); });
  ASSERT_TRUE(test::Eventually(30, [&] {
    return frozen.Called() && Metric(*control_, "vsurg_placements_in_flight") == 1;
  })) << "the Create waits on the frozen node";
  AddNode("sim-a", 4);  // the frozen node no longer beats: declared down after the timeout
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(created.wait_for(std::chrono::seconds(90)), std::future_status::ready);
  auto c = created.get();
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->record.node, "sim-a");
  EXPECT_TRUE(control_->IsLive(static_cast<uint64_t>(c->record.id)));
  // Once the node was down, not after the create timeout (a liveness bound: half of it).
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
            options_.create_timeout_s / 2);
  EXPECT_EQ(Metric(*control_, "vsurg_placement_refusals_total{reason=\"node_failed\"}"), 1);
}

TEST_F(ClusterTest, WatchersGetTheNodesTelemetryThroughTheControlPlaneAndTheEnd) {
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  WaitForNodes(2);
  auto one = control_->Create("trainee-0", "arm-torsion");
  auto two = control_->Create("trainee-1", "arm-torsion");
  ASSERT_TRUE(one.ok() && two.ok());
  ASSERT_NE(one->record.node, two->record.node);  // one on each node
  std::mutex m;
  std::condition_variable cv;
  std::set<uint64_t> seen_all;
  int one_samples = 0;
  bool one_ended = false;
  const uint64_t all = control_->Subscribe(0, [&](const std::vector<SessionTelemetry>& list, bool) {
    std::lock_guard lock(m);
    for (const auto& t : list) seen_all.insert(t.id);
    cv.notify_all();
  });
  const uint64_t mine = control_->Subscribe(
      one->record.id, [&](const std::vector<SessionTelemetry>& list, bool ended) {
        std::lock_guard lock(m);
        for (const auto& t : list) {
          EXPECT_EQ(t.id, static_cast<uint64_t>(one->record.id));
          EXPECT_EQ(t.scene, "arm-torsion");
          EXPECT_EQ(t.trainee, "trainee-0");
          ++one_samples;
        }
        if (ended) one_ended = true;
        cv.notify_all();
      });
  {
    std::unique_lock lock(m);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::seconds(5), [&] {
      return seen_all.size() == 2 && one_samples > 0;
    })) << "both nodes' sessions reach one watcher through the control plane";
  }
  ASSERT_TRUE(control_->Stop(one->record.id, "done").ok());
  {
    std::unique_lock lock(m);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::seconds(5), [&] { return one_ended; }))
        << "a watcher of one session is told when it ends";
  }
  control_->Unsubscribe(mine);
  control_->Unsubscribe(all);
}

// Telemetry comes by one stream per node, and only from the nodes someone on this replica
// watches: a watcher of one session opens its node's stream alone, with the watched session's
// surface; a watcher of every session opens every node's, without surfaces; no watcher, no stream.
TEST_F(ClusterTest, TelemetryStreamsOnlyFromTheNodesSomeoneWatchesAndSurfacesOnlyForAView) {
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  WaitForNodes(2);
  auto one = control_->Create("trainee-0", "arm-torsion");
  auto two = control_->Create("trainee-1", "arm-torsion");
  ASSERT_TRUE(one.ok() && two.ok());
  ASSERT_NE(one->record.node, two->record.node);
  ASSERT_TRUE(control_->Start(one->record.id).ok());
  std::mutex m;
  std::condition_variable cv;
  int surfaces_in_view = 0, lists_of_all = 0, surfaces_in_all = 0;
  std::set<uint64_t> in_all;
  const uint64_t view =
      control_->Subscribe(one->record.id, [&](const std::vector<SessionTelemetry>& list, bool) {
        std::lock_guard lock(m);
        for (const auto& t : list) surfaces_in_view += t.has_surface;
        cv.notify_all();
      });
  {
    std::unique_lock lock(m);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return surfaces_in_view > 0; }))
        << "the viewed session's surface reaches its watcher";
  }
  EXPECT_EQ(Metric(*control_, "vsurg_telemetry_streams"), 1)
      << "one watched session: its node's stream alone";
  const uint64_t all = control_->Subscribe(0, [&](const std::vector<SessionTelemetry>& list, bool) {
    std::lock_guard lock(m);
    ++lists_of_all;
    for (const auto& t : list) in_all.insert(t.id), surfaces_in_all += t.has_surface;
    cv.notify_all();
  });
  {
    std::unique_lock lock(m);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return in_all.size() == 2; }))
        << "a watcher of every session gets both nodes'";
  }
  EXPECT_EQ(Metric(*control_, "vsurg_telemetry_streams"), 2);
  control_->Unsubscribe(view);
  {
    std::unique_lock lock(m);
    const int seen = lists_of_all;
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return lists_of_all > seen + 10; });
    surfaces_in_all = 0;
    const int now = lists_of_all;
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return lists_of_all > now + 10; });
    EXPECT_GT(lists_of_all, now + 10);
    EXPECT_EQ(surfaces_in_all, 0) << "no one views a session: no surface crosses";
  }
  control_->Unsubscribe(all);
  EXPECT_TRUE(test::Eventually(10, [&] {
    return Metric(*control_, "vsurg_telemetry_streams") == 0;
  })) << "no watcher: no stream";
}

// Heartbeats stay in memory on the replica the node beats to: the node's row is written when it
// takes its name and when the row's lease needs renewing, not twice a second. A second replica,
// which hears nothing from the node for longer than the heartbeat timeout, keeps it up on the
// row's lease and places sessions on it.
TEST_F(ClusterTest, HeartbeatsStayInMemoryAndAnotherReplicaTrustsTheStoresLease) {
  auto second = SecondReplica();
  ASSERT_TRUE(second);
  const auto t0 = std::chrono::steady_clock::now();
  AddNode("sim-a", 8);
  WaitForNodes(1);
  // Past the heartbeat timeout, and many heartbeats.
  ASSERT_TRUE(test::Eventually(60, [&] {
    return Metric(*control_, "vsurg_heartbeats_received_total") >= 10 &&
           std::chrono::steady_clock::now() - t0 >
               std::chrono::duration<double>(options_.heartbeat_timeout_s + 1);
  }));
  const double received = Metric(*control_, "vsurg_heartbeats_received_total");
  const double written = Metric(*control_, "vsurg_heartbeat_store_writes_total");
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The acquisition, then one renewal each (store lease - max(half of it, timeout + 2 periods))
  // at most.
  const double renew_every = options_.store_lease_s - std::max(options_.store_lease_s / 2,
                                                               options_.heartbeat_timeout_s +
                                                                   2 * options_.heartbeat_period_s);
  // (Every heartbeat written would be about 2 per second of `elapsed`.)
  EXPECT_LE(written, 1 + std::ceil(elapsed / renew_every)) << received << " heartbeats received";
  EXPECT_EQ(Metric(*second, "vsurg_heartbeats_received_total"), 0) << "the node beats to one";
  EXPECT_EQ(Metric(*second, "vsurg_nodes{state=\"up\"}"), 1)
      << "the second replica trusts the lease";
  const auto row = control_store_->ListNodes().value().at(0);
  EXPECT_FALSE(row.down);
  EXPECT_EQ(row.epoch, 1);
  auto s = second->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->record.node, "sim-a");
  second.reset();
}

// The replica a node beats to is lost: the node's channel goes to the next one, whose first
// heartbeat from it is written (so no replica takes the old one's silence for the node's), and
// the node keeps its lease, its epoch and its sessions.
TEST_F(ClusterTest, ANodeWhoseReplicaIsLostBeatsToAnotherAndKeepsItsLeaseAndSessions) {
  auto second = SecondReplica();
  ASSERT_TRUE(second);
  node_control_ = "127.0.0.1:" + std::to_string(control_->port()) +
                  ",127.0.0.1:" + std::to_string(second->port());
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");  // not started: no station stalls it
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_GT(Metric(*control_, "vsurg_heartbeats_received_total"), 0) << "it beats to the first";
  control_->Shutdown();
  ASSERT_TRUE(test::Eventually(60, [&] {
    return Metric(*second, "vsurg_heartbeats_received_total") >= 4;
  })) << "the node never reached the second replica";
  // Past the heartbeat timeout since the first replica last heard it.
  std::this_thread::sleep_for(std::chrono::duration<double>(options_.heartbeat_timeout_s));
  const auto row = second_store_->ListNodes().value().at(0);
  EXPECT_FALSE(row.down);
  EXPECT_EQ(row.epoch, 1);
  EXPECT_EQ(a.lease.epoch(), 1);
  EXPECT_TRUE(a.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  EXPECT_TRUE(second->IsLive(s->record.id));
  EXPECT_EQ(Metric(*second, "vsurg_nodes{state=\"up\"}"), 1);
  second.reset();
}

// A node and the replica it beat to both gone: no replica hears it, and another declares it down
// once the row's lease has lapsed (never before), aborting its sessions.
TEST_F(ClusterTest, ANodeHeardByNoReplicaIsDownWhenItsStoresLeaseLapses) {
  auto second = SecondReplica();
  ASSERT_TRUE(second);
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_->port()),
                                     grpc::InsecureChannelCredentials());
  auto stub = v1::ClusterService::NewStub(channel);
  v1::NodeHeartbeat beat;
  beat.set_name("sim-gone");
  beat.set_grpc_address("192.0.2.1:9");  // TEST-NET-1: nothing answers (the probe decides nothing)
  beat.set_udp_host("127.0.0.1");
  beat.set_udp_port(1);
  beat.set_capacity(8);
  beat.set_instance("gone-process");
  grpc::ClientContext ctx;
  ctx.AddMetadata("authorization", std::string("Bearer ") + kToken);
  v1::NodeLeaseReply reply;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(stub->Acquire(&ctx, beat, &reply).ok());
  control_->Shutdown();  // the replica that heard it, gone before it could see the silence
  const auto down = [&] { return second_store_->ListNodes().value().at(0).down; };
  EXPECT_TRUE(test::Eventually(options_.store_lease_s + 30, down, std::chrono::milliseconds(50)));
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(waited, options_.store_lease_s - 0.05) << "declared down before its lease lapsed";
  second.reset();
}

// A session's record while it runs is on its node: the control plane reads it through the
// internal API (the session page's history); once ended, the node has kept it in the shared store.

}  // namespace
}  // namespace vsurg::server::cluster
