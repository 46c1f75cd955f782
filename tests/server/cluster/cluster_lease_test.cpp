// Leases and epochs: records through the control plane, a node the site gave up on, a second
// process under a live name, late readiness, the token and the site-wide trainee limit.
#include "tests/server/cluster/cluster_fixture.h"

namespace vsurg::server::cluster {
namespace {

using namespace test_cluster;  // NOLINT: the suites' fixture and helpers

TEST_F(ClusterTest, ALiveSessionsRecordIsReadThroughTheControlPlaneAndKeptWhenItEnds) {
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  boost::asio::io_context io;
  boost::asio::ip::udp::socket sock(io, boost::asio::ip::udp::v4());
  wire::Codec codec;
  uint64_t seq = 0;
  auto drive = [&] {  // a few stylus samples of a 1 kHz station
    for (int i = 0; i < 5; ++i) {
      wire::StylusMessage m;
      ++seq;
      m.sample.time = 1e-3 * static_cast<double>(seq);
      m.sample.position = Eigen::Vector3d(0, 0, 0.3);
      std::vector<uint8_t> buf(wire::kMaxDatagram);
      const size_t n = codec.EncodeStylus(m,
                                          {wire::kProtocolVersion, wire::PayloadType::kStylusState,
                                           static_cast<uint64_t>(s->record.id), seq},
                                          wire::Authenticator(s->key), buf);
      sock.send_to(boost::asio::buffer(buf.data(), n),
                   {boost::asio::ip::make_address("127.0.0.1"), a.endpoint->port()});
    }
  };
  auto samples = [&]() -> size_t {
    auto trace = control_->Trace(s->record.id);  // ClusterSessions → NodeService/Trace
    if (!trace.ok()) return 0;
    return nlohmann::json::parse(*trace)["series"]["time_s"].size();
  };
  test::Eventually(20, [&] {
    drive();
    return samples() >= 3;
  });
  ASSERT_GE(samples(), 3u) << "the node's record of the live session, through the control plane";
  ASSERT_TRUE(control_->Stop(s->record.id, "done").ok());
  test::Eventually(10, [&] { return control_store_->GetSessionTrace(s->record.id).ok(); });
  auto kept = control_store_->GetSessionTrace(s->record.id);
  ASSERT_TRUE(kept.ok()) << kept.error().message;
  EXPECT_GE(nlohmann::json::parse(*kept)["series"]["time_s"].size(), 3u);
  EXPECT_EQ(control_->Trace(s->record.id).error().code, ErrorCode::kNotFound);
}

// The site gives up on a node (its heartbeats were late past the timeout: a frozen process, a cut
// network) while the node itself goes on. When it next reaches the control plane it learns that
// its lease is gone: it drops its sessions without writing them (the aborted session stays
// aborted, with no trial recorded), its endpoint answers none of their stations, and it takes the
// name again under a new epoch and serves new sessions.
TEST_F(ClusterTest, ANodeTheSiteGaveUpOnDropsItsSessionsUnwrittenAndServesAgainUnderANewEpoch) {
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  ASSERT_EQ(a.lease.epoch(), 1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  ASSERT_EQ(a.sessions->LiveCount(), 1);
  // What the watchdog does to a node silent for 2 s, done now: the node is marked down and its
  // session aborted, while the node process goes on.
  const int64_t now = db::NowUs();
  ASSERT_EQ(control_store_->MarkNodeDown("sim-a", now + 60'000'000, now, "declared down").value(),
            1);
  test::Eventually(10, [&] { return a.sessions->LiveCount() == 0 && a.lease.epoch() == 2; });
  EXPECT_EQ(a.sessions->LiveCount(), 0) << "the node kept the session the site aborted";
  EXPECT_EQ(a.lease.epoch(), 2) << "the node did not take its name again";
  auto row = control_store_->GetSession(s->record.id);
  ASSERT_TRUE(row.ok());
  EXPECT_EQ(row->state, SessionState::kAborted);
  EXPECT_EQ(row->end_reason, "declared down");
  EXPECT_FALSE(control_store_->GetTrialMetrics(s->record.id).value().has_value());
  // Its station's datagrams find no session there any more: never answered.
  const auto before = a.endpoint->counters();
  {
    boost::asio::io_context io;
    boost::asio::ip::udp::socket sock(io, boost::asio::ip::udp::v4());
    wire::StylusMessage m;
    m.sample.time = 1;
    m.sample.position = Eigen::Vector3d(0, 0, 0.05);
    std::vector<uint8_t> buf(wire::kMaxDatagram);
    wire::Codec codec;
    const size_t n = codec.EncodeStylus(m,
                                        {wire::kProtocolVersion, wire::PayloadType::kStylusState,
                                         static_cast<uint64_t>(s->record.id), 1},
                                        wire::Authenticator(s->key), buf);
    sock.send_to(boost::asio::buffer(buf.data(), n),
                 {boost::asio::ip::make_address("127.0.0.1"), a.endpoint->port()});
  }
  test::Eventually(10, [&] { return a.endpoint->counters().received != before.received; });
  const auto after = a.endpoint->counters();
  EXPECT_EQ(after.received, before.received + 1);
  EXPECT_EQ(after.answered, before.answered);
  // Up again under the new epoch: it takes new sessions.
  WaitForNodes(1);
  auto next = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(next.ok()) << next.error().message;
  EXPECT_EQ(next->record.node, "sim-a");
  EXPECT_EQ(control_->Get(next->record.id)->state, SessionState::kCreated);
}

// A second process started under a live node's name (a mistyped deployment, a pod started twice)
// is refused with a clear error and takes nothing away: the live node keeps its session, its
// address in the registry and its lease.
TEST_F(ClusterTest, ASecondProcessUnderALiveNodesNameIsRefusedAndTakesNothing) {
  Node& a = AddNode("sim-a", 8);
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  const std::string address = control_store_->ListNodes().value().at(0).grpc_address;
  Node twin;
  twin.store = std::move(db::Store::Open({.path = db_.uri()})).value();
  SessionManagerOptions so;
  so.node = "sim-a";
  so.lease = &twin.lease;
  EndpointOptions eo;
  eo.lease = &twin.lease;
  twin.endpoint = std::move(UdpEndpoint::Create(eo)).value();
  twin.sessions = SessionManager::Open(*twin.store, twin.endpoint.get(), so).value();
  NodeOptions no;
  no.name = "sim-a";
  no.control = "127.0.0.1:" + std::to_string(control_->port());
  no.udp_host = "127.0.0.1";
  no.udp_port = twin.endpoint->port();
  no.capacity = 8;
  no.cluster = options_;
  no.lease = &twin.lease;
  auto refused = NodeAgent::Start(*twin.sessions, no);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kAlreadyExists);
  EXPECT_EQ(refused.error().field, "node-name");
  EXPECT_NE(refused.error().message.find("held by another live process"), std::string::npos)
      << refused.error().message;
  EXPECT_FALSE(twin.lease.held());
  EXPECT_EQ(control_->Get(s->record.id)->state, SessionState::kCreated);
  EXPECT_TRUE(a.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  const auto nodes = control_store_->ListNodes().value();
  ASSERT_EQ(nodes.size(), 1u);
  EXPECT_EQ(nodes[0].grpc_address, address);
  EXPECT_EQ(nodes[0].epoch, 1);
  EXPECT_TRUE(a.lease.Valid());
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  twin.sessions.reset();
  twin.endpoint.reset();
}

// A Create that outlived its caller (a station on a starved machine asks again once its deadline
// passes, while the node still builds the scene) leaves nothing behind: the node's new session
// is aborted at once, not after the 60 s not-started timeout, so it holds neither the trainee's
// slot (two per trainee here) nor the node's room, and the trainee's next Creates are placed.
// Without it, each retry left one such session: 62 in one rolling restart beside two CPU hogs.
TEST_F(ClusterTest, ASessionReadyAfterItsCreatorStoppedWaitingIsAbortedAtOnce) {
  AddNode("sim-a", 2);
  WaitForNodes(1);
  for (int attempt = 0; attempt < 3; ++attempt) {
    const CallerDeadline gone(std::chrono::system_clock::now() - std::chrono::seconds(1));
    auto late = control_->Create("tina", "sphere-palpation-256");
    ASSERT_FALSE(late.ok()) << "attempt " << attempt;
    EXPECT_EQ(late.error().code, ErrorCode::kUnavailable);
    EXPECT_NE(late.error().message.find("after its creator stopped waiting"), std::string::npos)
        << late.error().message;
  }
  auto mine = control_store_->ListSessions(std::string("tina")).value();
  ASSERT_EQ(mine.size(), 3u) << "each attempt was built on the node";
  for (const db::SessionRecord& r : mine) {
    EXPECT_EQ(r.state, SessionState::kAborted) << r.id;
    EXPECT_NE(r.end_reason.find("abandoned"), std::string::npos) << r.end_reason;
    EXPECT_FALSE(control_->IsLive(static_cast<uint64_t>(r.id)));
  }
  EXPECT_EQ(nodes_[0]->sessions->LiveCount(), 0);
  // The trainee's two slots and the node's two places are free: a caller that waits gets both.
  for (int i = 0; i < 2; ++i) {
    auto c = control_->Create("tina", "sphere-palpation-256");
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_EQ(c->record.state, SessionState::kCreated);
  }
  // A started session is never taken for abandoned: the node refuses, and it stays live.
  auto started = control_store_->ListSessions(std::string("tina")).value();
  const auto live = std::find_if(started.begin(), started.end(), [](const db::SessionRecord& r) {
    return r.state == SessionState::kCreated;
  });
  ASSERT_NE(live, started.end());
  ASSERT_TRUE(control_->Start(static_cast<uint64_t>(live->id)).ok());
  auto refused = nodes_[0]->sessions->Abandon(static_cast<uint64_t>(live->id), "abandoned");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kFailedPrecondition);
  EXPECT_TRUE(control_->IsLive(static_cast<uint64_t>(live->id)));
  EXPECT_EQ(Metric(*control_, "vsurg_placement_refusals_total{reason=\"caller_gone\"}"), 3);
}

TEST_F(ClusterTest, InternalCallsWithoutTheTokenAreRefusedAndTheTraineeLimitIsSiteWide) {
  AddNode("sim-a", 8);
  AddNode("sim-b", 8);
  WaitForNodes(2);
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_->port()),
                                     grpc::InsecureChannelCredentials());
  auto stub = v1::ClusterService::NewStub(channel);
  v1::NodeHeartbeat forged;
  forged.set_name("sim-evil");
  forged.set_grpc_address("127.0.0.1:1");
  forged.set_udp_host("127.0.0.1");
  forged.set_udp_port(1);
  forged.set_capacity(100);
  for (const char* token :
       {"", "Bearer wrong-token-0123456789", "Bearer test-cluster-token-012345678"}) {
    grpc::ClientContext ctx;
    if (*token) ctx.AddMetadata("authorization", token);
    v1::HeartbeatReply reply;
    EXPECT_EQ(stub->Heartbeat(&ctx, forged, &reply).error_code(), grpc::StatusCode::UNAUTHENTICATED)
        << token;
    grpc::ClientContext ctx2;
    if (*token) ctx2.AddMetadata("authorization", token);
    v1::NodeLeaseReply lease;
    EXPECT_EQ(stub->Acquire(&ctx2, forged, &lease).error_code(), grpc::StatusCode::UNAUTHENTICATED)
        << token;
  }
  EXPECT_EQ(control_store_->ListNodes().value().size(), 2u) << "no forged node registered";
  // Two live sessions for one trainee, on two nodes: a third is refused by the control plane.
  ASSERT_TRUE(control_->Create("tia", "arm-torsion").ok());
  ASSERT_TRUE(control_->Create("tia", "arm-torsion").ok());
  auto third = control_->Create("tia", "arm-torsion");
  ASSERT_FALSE(third.ok());
  EXPECT_EQ(third.error().code, ErrorCode::kResourceExhausted);
  // A token shorter than 16 characters is refused at start.
  ClusterOptions weak = options_;
  weak.token = "short";
  EXPECT_EQ(ClusterSessions::Start(*control_store_, weak).error().field, "cluster-token");
}

}  // namespace
}  // namespace vsurg::server::cluster
