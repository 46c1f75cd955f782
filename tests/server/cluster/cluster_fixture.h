// The cluster suites' fixture: the control and sim roles in one process, over a real PostgreSQL
// and real gRPC on loopback (a control replica, nodes added by the test), and a frozen node.
#pragma once

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
#include "tests/support/press_and_hold.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"
#include "vsurg/v1/cluster.grpc.pb.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::server::cluster::test_cluster {

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
inline int HttpStatus(int port, const std::string& method, const std::string& target,
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

}  // namespace vsurg::server::cluster::test_cluster
