// haptic-rtt's --dashboard-clients (bench/rtt_commands.cpp): the server's own stack around the
// endpoint, and dashboard clients that follow it as browsers do. Only that file includes it.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "db/store.h"
#include "proto/wire/asio.h"
#include "server/http/http_server.h"
#include "server/net/udp_endpoint.h"
#include "server/session/session_manager.h"

namespace vsurg::bench {

namespace asio = boost::asio;

// --dashboard-clients: the server's stack around the endpoint (a store in a temporary folder, the
// session manager, the HTTP dashboard) and web clients that each follow the live page (every
// session, 4 Hz) and one session's page (10 Hz, with its deformed surface), reading as a browser
// does.
struct ServerStack {
  std::filesystem::path dir;
  std::unique_ptr<vsurg::db::Store> store;
  std::unique_ptr<vsurg::server::SessionManager> sessions;
  std::unique_ptr<vsurg::server::HttpServer> server;
  std::string token;
  std::vector<uint64_t> ids;
  std::vector<vsurg::wire::SessionKey> keys;
  asio::io_context io;
  std::vector<std::unique_ptr<asio::ip::tcp::socket>> sockets;
  std::vector<std::array<char, 65536>> buffers;
  std::atomic<uint64_t> bytes{0};
  std::thread thread;

  static vsurg::Expected<std::unique_ptr<ServerStack>> Start(vsurg::server::UdpEndpoint& endpoint,
                                                             const std::string& scene, int n,
                                                             int pool_workers,
                                                             double quasi_static_interval_s) {
    auto s = std::make_unique<ServerStack>();
    s->dir = std::filesystem::temp_directory_path() /
             ("vsurg_bench_stack_" + std::to_string(::getpid()));
    std::filesystem::remove_all(s->dir);
    std::filesystem::create_directories(s->dir);
    auto store = vsurg::db::Store::Open({.path = (s->dir / "vsurg.db").string()});
    if (!store.ok()) return store.error();
    s->store = std::move(store).value();
    auto token = s->store->InitAdmin("admin");
    if (!token.ok()) return token.error();
    s->token = *token;
    vsurg::server::SessionManagerOptions so;
    so.max_live_sessions = std::max(256, n);
    so.deformation_workers = pool_workers;
    so.quasi_static_interval_s = quasi_static_interval_s;
    s->sessions = vsurg::server::SessionManager::Open(*s->store, &endpoint, so).value();
    auto server = vsurg::server::HttpServer::Start(*s->store, *s->sessions, {});
    if (!server.ok()) return server.error();
    s->server = std::move(server).value();
    for (int i = 0; i < n; ++i) {
      const std::string trainee = "trainee-" + std::to_string(i);
      if (auto u = s->store->CreateUser(trainee, vsurg::db::Role::kTrainee, "bench"); !u.ok())
        return u.error();
      auto created = s->sessions->Create(trainee, scene);
      if (!created.ok()) return created.error();
      const auto id = static_cast<uint64_t>(created->record.id);
      if (auto started = s->sessions->Start(id); !started.ok()) return started.error();
      s->ids.push_back(id);
      s->keys.push_back(created->key);
    }
    return s;
  }

  void Follow(int clients) {
    const asio::ip::tcp::endpoint to(asio::ip::make_address("127.0.0.1"),
                                     static_cast<uint16_t>(server->port()));
    buffers.resize(static_cast<size_t>(2 * clients));
    for (int c = 0; c < clients; ++c) {
      for (const std::string& path :
           {std::string("/api/v1/live/events"),
            "/api/v1/sessions/" + std::to_string(ids[static_cast<size_t>(c) % ids.size()]) +
                "/events"}) {
        auto socket = std::make_unique<asio::ip::tcp::socket>(io);
        socket->connect(to);
        const std::string request = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\n" +
                                    "Authorization: Bearer " + token + "\r\n\r\n";
        asio::write(*socket, asio::buffer(request));
        sockets.push_back(std::move(socket));
        Read(sockets.size() - 1);
      }
    }
    thread = std::thread([this] { io.run(); });
  }
  void Read(size_t k) {
    sockets[k]->async_read_some(asio::buffer(buffers[k]), [this, k](auto ec, size_t n) {
      if (ec) return;
      bytes.fetch_add(n, std::memory_order_relaxed);
      Read(k);
    });
  }
  void Stop() {
    asio::post(io, [this] {
      for (auto& s : sockets) {
        boost::system::error_code ec;
        s->close(ec);
      }
    });
    if (thread.joinable()) thread.join();
    server->Shutdown();
    sessions->Shutdown();
    sessions.reset();
    server.reset();
    store.reset();
    std::filesystem::remove_all(dir);
  }
};

}  // namespace vsurg::bench
