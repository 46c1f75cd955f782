// The control and sim roles in one process, over a real PostgreSQL and real gRPC on loopback:
// placement, capacity, drain, a node gone or silent, the cluster token, the site-wide per-trainee
// limit.
#include "server/cluster/cluster.h"

#include <arpa/inet.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <nlohmann/json.hpp>

#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "db/store.h"
#include "proto/wire/asio.h"
#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"
#include "server/cluster/cluster_common.h"
#include "server/control/control_plane.h"
#include "server/http/http_server.h"
#include "server/net/lease.h"
#include "server/net/udp_endpoint.h"
#include "server/ops/metrics.h"
#include "server/session/caller_deadline.h"
#include "server/session/session_manager.h"
#include "tests/support/postgres.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"
#include "vsurg/v1/cluster.grpc.pb.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::server::cluster {
namespace {

constexpr const char* kToken = "test-cluster-token-0123456789";

// A node whose port accepts connections and never answers: a frozen process (the kernel completes
// each handshake, nobody reads). With `handshake`, a thread accepts each connection and sends
// HTTP/2's opening SETTINGS frame before it freezes, as a process stopped after its connections
// were up: the control plane's calls on it then wait for their deadlines. Acquire registers it
// with the control plane at epoch 1.
class FrozenNode {
 public:
  explicit FrozenNode(bool handshake = false) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    ok_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), len) == 0 &&
          ::listen(fd_, 16) == 0 &&
          ::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0;
    port_ = ntohs(addr.sin_port);
    if (ok_ && handshake)
      acceptor_ = std::thread([this] {
        static constexpr unsigned char kSettings[9] = {0, 0, 0, 4, 0, 0, 0, 0, 0};
        while (!closing_) {
          pollfd p{fd_, POLLIN, 0};
          if (::poll(&p, 1, 20) <= 0) continue;
          const int c = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
          if (c < 0) continue;
          if (::write(c, kSettings, sizeof kSettings) != sizeof kSettings) ADD_FAILURE();
          std::lock_guard lock(mutex_);
          taken_.push_back(c);
        }
      });
  }
  ~FrozenNode() { Close(); }
  bool ok() const { return ok_; }
  // Its process is gone: its connections are closed and the ones waiting are reset.
  void Close() {
    closing_ = true;
    if (acceptor_.joinable()) acceptor_.join();
    std::lock_guard lock(mutex_);
    for (int c : taken_) ::close(c);
    taken_.clear();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // Someone connected: without `handshake`, a connection waits in the listen queue (taken here);
  // with it, the acceptor took one.
  bool Called() {
    std::lock_guard lock(mutex_);
    if (acceptor_.joinable()) return !taken_.empty();
    const int c = ::accept(fd_, nullptr, nullptr);
    if (c < 0) return false;
    taken_.push_back(c);
    return true;
  }
  v1::NodeLeaseReply Acquire(int control_port, const std::string& name, int capacity) {
    auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_port),
                                       grpc::InsecureChannelCredentials());
    auto stub = v1::ClusterService::NewStub(channel);
    v1::NodeHeartbeat beat;
    beat.set_name(name);
    beat.set_grpc_address("127.0.0.1:" + std::to_string(port_));
    beat.set_udp_host("127.0.0.1");
    beat.set_udp_port(1);
    beat.set_capacity(capacity);
    beat.set_instance(name + "-process");
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", std::string("Bearer ") + kToken);
    v1::NodeLeaseReply reply;
    EXPECT_TRUE(stub->Acquire(&ctx, beat, &reply).ok());
    return reply;
  }

 private:
  int fd_ = -1, port_ = 0;
  bool ok_ = false;
  std::atomic<bool> closing_{false};
  std::thread acceptor_;
  std::mutex mutex_;
  std::vector<int> taken_;
};

// One HTTP/1.1 request on its own connection with a bearer token: the status, or 0 when no answer
// came within `seconds` (asynchronous: Beast's stream expiry bounds only those).
int HttpStatus(int port, const std::string& method, const std::string& target,
               const std::string& token, const std::string& body, double seconds) {
  namespace beast = boost::beast;
  namespace http = beast::http;
  boost::asio::io_context io;
  beast::tcp_stream stream(io);
  http::request<http::string_body> req{method == "POST" ? http::verb::post : http::verb::get,
                                       target, 11};
  req.set(http::field::host, "127.0.0.1");
  req.set(http::field::authorization, "Bearer " + token);
  if (!body.empty()) req.set(http::field::content_type, "application/json");
  req.body() = body;
  req.prepare_payload();
  beast::flat_buffer buffer;
  http::response<http::string_body> res;
  int status = 0;
  stream.expires_after(std::chrono::milliseconds(static_cast<int>(seconds * 1000)));
  stream.async_connect({boost::asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)},
                       [&](beast::error_code ec) {
                         if (ec) return;
                         http::async_write(stream, req, [&](beast::error_code written, size_t) {
                           if (written) return;
                           http::async_read(stream, buffer, res,
                                            [&](beast::error_code read, size_t) {
                                              if (!read)
                                                status = static_cast<int>(res.result_int());
                                            });
                         });
                       });
  io.run();
  return status;
}

class ClusterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    control_store_ = std::move(db::Store::Open({.path = db_.uri()})).value();
    options_.token = kToken;
    options_.listen = "127.0.0.1:0";
    options_.max_sessions_per_user = 2;
    // A lease long enough that a loaded machine (two test jobs beside two CPU hogs) never starves
    // a node's heartbeats past it (at 2 s a node lost its lease mid-test); the tests that wait
    // for a timeout wait for this one.
    options_.heartbeat_timeout_s = 6;
    options_.create_timeout_s = 120;
    Configure();
    auto c = ClusterSessions::Start(*control_store_, options_);
    ASSERT_TRUE(c.ok()) << c.error().message;
    control_ = std::move(c).value();
  }
  void TearDown() override {
    for (auto& n : nodes_) {  // the agent, then the sessions, then the endpoint they use
      n->agent.reset();
      n->sessions.reset();
      n->endpoint.reset();
    }
    nodes_.clear();
    control_.reset();
  }

  struct Node {
    Lease lease;
    std::unique_ptr<db::Store> store;
    std::unique_ptr<UdpEndpoint> endpoint;
    std::unique_ptr<SessionManager> sessions;
    std::unique_ptr<NodeAgent> agent;
  };
  virtual void Configure() {}  // the control replica's options, before it starts

  Node& AddNode(const std::string& name, int capacity) {
    auto n = TryAddNode(name, capacity, options_);
    EXPECT_TRUE(n.ok()) << n.error().message;
    return *n.value();
  }
  // A node with these cluster options (token, TLS files); on failure nothing is kept.
  Expected<Node*> TryAddNode(const std::string& name, int capacity, const ClusterOptions& cluster) {
    auto n = std::make_unique<Node>();
    n->store = std::move(db::Store::Open({.path = db_.uri()})).value();
    SessionManagerOptions so;
    so.node = name;
    so.lease = &n->lease;
    EndpointOptions eo;
    eo.address = "127.0.0.1";
    eo.port = 0;
    eo.realtime_priority = 0;
    eo.lease = &n->lease;
    n->endpoint = std::move(UdpEndpoint::Create(eo)).value();
    n->sessions = SessionManager::Open(*n->store, n->endpoint.get(), so).value();
    NodeOptions no;
    no.name = name;
    no.control =
        node_control_.empty() ? "127.0.0.1:" + std::to_string(control_->port()) : node_control_;
    no.udp_host = "127.0.0.1";
    no.udp_port = n->endpoint->port();
    no.capacity = capacity;
    no.cluster = cluster;
    no.lease = &n->lease;
    no.migrate_on_drain = migrate_;
    auto agent = NodeAgent::Start(*n->sessions, no);
    if (!agent.ok()) {
      n->sessions.reset();
      n->endpoint.reset();
      return agent.error();
    }
    n->agent = std::move(agent).value();
    nodes_.push_back(std::move(n));
    return nodes_.back().get();
  }
  // Waits until the registry shows `count` nodes up.
  void WaitForNodes(size_t count) {
    ASSERT_TRUE(test::Eventually(10, [&] {
      const auto nodes = control_store_->ListNodes();
      size_t up = 0;
      if (nodes.ok())
        for (const auto& n : *nodes) up += !n.down;
      return up == count;
    })) << "the nodes did not register";
  }
  Node& NodeNamed(const std::string& name) { return *nodes_[name == "sim-a" ? 0 : 1]; }
  std::map<std::string, int> PerNode() {
    std::map<std::string, int> out;
    const auto counts = control_store_->LiveSessionsByNode();  // kept: the loop reads into it
    for (const auto& [node, n] : counts.value()) out[node] = n;
    return out;
  }

  // A second control replica on the same database (its own store connection).
  std::unique_ptr<ClusterSessions> SecondReplica() {
    second_store_ = std::move(db::Store::Open({.path = db_.uri()})).value();
    auto c = ClusterSessions::Start(*second_store_, options_);
    EXPECT_TRUE(c.ok()) << c.error().message;
    return c.ok() ? std::move(c).value() : nullptr;
  }
  // One sample of a replica's metrics (the first whose name and labels start with `series`).
  static double Metric(const ClusterSessions& c, const std::string& series) {
    ops::MetricsText m;
    c.Collect(m);
    const std::string& text = m.str();
    for (size_t at = 0; (at = text.find(series, at)) != std::string::npos; ++at)
      if (at == 0 || text[at - 1] == '\n') {
        const size_t space = text.find(' ', at);
        return std::stod(text.substr(space + 1, text.find('\n', space) - space - 1));
      }
    return -1;
  }

  test::PostgresDatabase db_;
  std::unique_ptr<db::Store> control_store_, second_store_;
  ClusterOptions options_;
  std::string node_control_;  // the nodes' --control (default: the first replica)
  bool migrate_ = true;       // the nodes' migrate_on_drain
  std::unique_ptr<ClusterSessions> control_;
  std::vector<std::unique_ptr<Node>> nodes_;
};

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
  auto joined = control_->Join(static_cast<uint64_t>(first.id));
  ASSERT_TRUE(joined.ok()) << joined.error().message;
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
  auto joined = control_->Join(live->record.id);
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
  EXPECT_FALSE(stub->Join(ctx("trainee-10", 1).get(), ref, &joined).ok());
  v1::Session got;
  const grpc::Status get = stub->Get(ctx("trainee-10", 30).get(), ref, &got);
  ASSERT_TRUE(get.ok()) << get.error_message();
  EXPECT_EQ(got.id(), ref.id());
  {
    const CallerDeadline caller(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
    const auto t0 = std::chrono::steady_clock::now();
    auto direct = control_->Join(ref.id());
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
// watches: a watcher of one session opens its node's stream alone, with that session's surface;
// a watcher of every session opens every node's, without surfaces; no watcher, no stream.
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

// --- Mutual TLS on the internal API (docs/SCALING.md, "Mutual TLS") ---

// Certificates from deploy/cluster_certs.sh: a site CA ("site") naming vsurg-control, sim-a and
// sim-b, and a stranger's CA ("other") naming the same.
class ClusterTlsTest : public ClusterTest {
 protected:
  void Configure() override {
    for (const char* ca : {"site", "other"}) {
      const std::string cmd = std::string(VSURG_SOURCE_DIR) + "/deploy/cluster_certs.sh " +
                              dir_.path().string() + "/" + ca + " vsurg-control sim-a sim-b";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    }
    options_ = As("site", "vsurg-control");
    options_.listen = "127.0.0.1:0";
    options_.health_listen = "127.0.0.1:0";
  }
  // The fixture's options with `name`'s certificate from CA `ca`, trusting the site's CA.
  ClusterOptions As(const std::string& ca, const std::string& name) const {
    ClusterOptions o = options_;
    o.tls_cert = Pki(ca, name + ".pem");
    o.tls_key = Pki(ca, name + ".key");
    o.tls_ca = Pki("site", "ca.pem");
    o.tls_refresh_s = 1;
    o.health_listen.clear();
    return o;
  }
  std::string Pki(const std::string& ca, const std::string& file) const {
    return (dir_.path() / ca / file).string();
  }
  // Replaces `to` with `from` the way a renewal does (a rename: never half a file).
  static void Renew(const std::string& from, const std::string& to) {
    std::filesystem::copy_file(from, to + ".new",
                               std::filesystem::copy_options::overwrite_existing);
    std::filesystem::rename(to + ".new", to);
  }
  // A call to a node's NodeService as `caller` (its certificate), with the site's token.
  grpc::Status CallNode(const Node& node, const ClusterOptions& caller, const std::string& name) {
    auto stub = v1::NodeService::NewStub(Channel("127.0.0.1:" + std::to_string(node.agent->port()),
                                                 WatchTlsFiles(caller).value(), name));
    auto ctx = CallContext(kToken, 10);
    v1::NodeTelemetry reply;
    return stub->Telemetry(ctx.get(), {}, &reply);
  }
  // A heartbeat for `node` to the control plane as `caller`.
  grpc::Status Beat(const ClusterOptions& caller, const std::string& node) {
    auto stub =
        v1::ClusterService::NewStub(Channel("127.0.0.1:" + std::to_string(control_->port()),
                                            WatchTlsFiles(caller).value(), "vsurg-control"));
    auto ctx = CallContext(kToken, 10);
    v1::NodeHeartbeat beat;
    beat.set_name(node);
    v1::HeartbeatReply reply;
    return stub->Heartbeat(ctx.get(), beat, &reply);
  }

  test::TempDir dir_{"cluster_tls"};
};

TEST_F(ClusterTlsTest, ANodesNameIsBoundToItsCertificate) {
  ASSERT_TRUE(options_.tls());
  // sim-a with its own certificate: registered, and the control plane reaches it (checking that
  // the address it dials serves sim-a) to create and start a session.
  Node& a = *TryAddNode("sim-a", 4, As("site", "sim-a")).value();
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  EXPECT_TRUE(a.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  // A process holding sim-a's certificate and the token cannot take another name: refused at
  // start with the reason, nothing registered under it.
  auto b = TryAddNode("sim-b", 4, As("site", "sim-a"));
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().code, ErrorCode::kPermissionDenied);
  EXPECT_EQ(b.error().field, "node-name");
  EXPECT_NE(b.error().message.find("names sim-a, not node sim-b"), std::string::npos)
      << b.error().message;
  // Nor beat for a name it does not carry (sim-b's certificate for sim-a's name); and the control
  // replicas' certificate names no node.
  EXPECT_EQ(Beat(As("site", "sim-b"), "sim-a").error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(Beat(As("site", "vsurg-control"), "vsurg-control").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  const auto nodes = control_store_->ListNodes().value();
  ASSERT_EQ(nodes.size(), 1u);
  EXPECT_EQ(nodes[0].name, "sim-a");
  EXPECT_EQ(nodes[0].epoch, 1);
  EXPECT_TRUE(a.lease.Valid());
}

TEST_F(ClusterTlsTest, OnlyTheSitesCertificatesGetInAndOnlyAControlReplicaCallsANode) {
  Node& a = *TryAddNode("sim-a", 4, As("site", "sim-a")).value();
  WaitForNodes(1);
  // A control replica's certificate calls a node; a node's own (or another node's) does not,
  // token or not.
  EXPECT_TRUE(CallNode(a, As("site", "vsurg-control"), "sim-a").ok());
  EXPECT_EQ(CallNode(a, As("site", "sim-b"), "sim-a").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(CallNode(a, As("site", "sim-a"), "sim-a").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  // A caller expecting another name at that address does not talk to it (the channel's check of
  // the server's certificate).
  EXPECT_EQ(CallNode(a, As("site", "vsurg-control"), "sim-b").error_code(),
            grpc::StatusCode::UNAVAILABLE);
  // Certificates from another CA, and plaintext, do not get past the handshake.
  EXPECT_EQ(Beat(As("other", "sim-a"), "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(CallNode(a, As("other", "vsurg-control"), "sim-a").error_code(),
            grpc::StatusCode::UNAVAILABLE);
  ClusterOptions plain = options_;
  plain.tls_cert = plain.tls_key = plain.tls_ca = "";
  EXPECT_EQ(Beat(plain, "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(CallNode(a, plain, "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(control_store_->ListNodes().value().size(), 1u);
  // The health check answers on its own plaintext port (what a probe reaches), and nothing else
  // is served there.
  ASSERT_GT(control_->health_port(), 0);
  auto health = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_->health_port()),
                                    grpc::InsecureChannelCredentials());
  grpc::GenericStub stub(health);
  grpc::Slice empty_slice("", 0);
  grpc::ByteBuffer request(&empty_slice, 1), response;
  for (const char* method :
       {"/grpc.health.v1.Health/Check", "/vsurg.v1.ClusterService/Heartbeat"}) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    std::promise<grpc::Status> done;
    stub.UnaryCall(&ctx, method, grpc::StubOptions(), &request, &response,
                   [&](grpc::Status st) { done.set_value(st); });
    const grpc::Status st = done.get_future().get();
    if (std::string(method).find("Health") != std::string::npos) {
      ASSERT_TRUE(st.ok()) << st.error_message();
      std::vector<grpc::Slice> slices;
      ASSERT_TRUE(response.Dump(&slices).ok());
      std::string bytes;
      for (const auto& sl : slices)
        bytes.append(reinterpret_cast<const char*>(sl.begin()), sl.size());
      EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // SERVING
    } else {
      EXPECT_EQ(st.error_code(), grpc::StatusCode::UNIMPLEMENTED);
    }
  }
  // Half a TLS configuration is refused at start, naming what is missing.
  ClusterOptions half = options_;
  half.tls_ca.clear();
  EXPECT_EQ(ClusterSessions::Start(*control_store_, half).error().field, "cluster-tls-ca");
  half = options_;
  half.tls_key = half.tls_cert;  // a certificate where the key should be
  EXPECT_EQ(ClusterSessions::Start(*control_store_, half).error().field, "cluster-tls-key");
}

TEST_F(ClusterTlsTest, ARenewedCertificateIsUsedWithoutARestart) {
  // A node starts with a certificate the site does not trust (a stranger's CA): it cannot get
  // in, and keeps asking.
  const ClusterOptions node = As("site", "sim-a");
  const std::string cert = dir_.path() / "sim-a.pem", key = dir_.path() / "sim-a.key";
  Renew(Pki("other", "sim-a.pem"), cert);
  Renew(Pki("other", "sim-a.key"), key);
  ClusterOptions renewing = node;
  renewing.tls_cert = cert;
  renewing.tls_key = key;
  renewing.heartbeat_timeout_s = 2;  // its start stops waiting after 3 s; its heartbeats go on
  auto a = TryAddNode("sim-a", 4, renewing);
  ASSERT_TRUE(a.ok()) << a.error().message;
  // Its heartbeat thread asks and is refused at the handshake; nothing gets in.
  const auto failed_beats = [&] {
    ops::MetricsText m;
    (*a)->agent->Collect(m);
    const std::string series = "vsurg_heartbeats_total{outcome=\"failed\"} ";
    const size_t at = m.str().find(series);
    return at == std::string::npos ? 0.0 : std::stod(m.str().substr(at + series.size()));
  };
  ASSERT_TRUE(test::Eventually(30, [&] { return failed_beats() >= 1; }));
  EXPECT_TRUE(control_store_->ListNodes().value().empty()) << "the stranger's certificate got in";
  EXPECT_FALSE((*a)->lease.held());
  // The site's certificate arrives in the same files.
  Renew(Pki("site", "sim-a.key"), key);
  Renew(Pki("site", "sim-a.pem"), cert);
  WaitForNodes(1);  // the same process, now with the renewed certificate
  EXPECT_TRUE(test::Eventually(30, [&] { return (*a)->lease.Valid(); }));
  // The control replica's own certificate renewed under it: new connections get the new one (a
  // certificate naming someone else, so a fresh caller expecting vsurg-control is refused), and
  // back.
  const std::string control_cert = options_.tls_cert, control_key = options_.tls_key;
  const std::string kept = dir_.path() / "control-kept";
  std::filesystem::copy_file(control_cert, kept + ".pem");
  std::filesystem::copy_file(control_key, kept + ".key");
  // A heartbeat from this test passes the handshake and the name check and is refused by the
  // handler (INVALID_ARGUMENT: it is no process's heartbeat); UNAVAILABLE is the handshake's
  // refusal. It passes before the renewal; right after it, either answer is possible until the
  // replica's watcher reads the files (a check there raced the watcher and failed under load).
  const auto handshake_passes = [&] {
    return Beat(node, "sim-a").error_code() == grpc::StatusCode::INVALID_ARGUMENT;
  };
  EXPECT_TRUE(handshake_passes());
  Renew(Pki("site", "sim-b.key"), control_key);
  Renew(Pki("site", "sim-b.pem"), control_cert);
  EXPECT_TRUE(test::Eventually(30, [&] {
    return Beat(node, "sim-a").error_code() == grpc::StatusCode::UNAVAILABLE;
  })) << "the control replica still presents its old certificate";
  // Back, the certificate first: for two reads the files hold a mismatched pair (a renewal caught
  // between its two renames), which must not stick. (The reads are gRPC's watcher thread on the
  // real clock, which takes no injected one; a watcher slower than this only tests less, it
  // cannot fail the test.)
  Renew(kept + ".pem", control_cert);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  Renew(kept + ".key", control_key);
  EXPECT_TRUE(test::Eventually(30, handshake_passes));
  EXPECT_TRUE((*a)->lease.Valid()) << "the node's own connection outlived the renewals";
}

}  // namespace
}  // namespace vsurg::server::cluster
