// The visual half of the UDP endpoint: each session's moved vertices (Simulation::
// TakeVisualFrame) sealed into SceneFrame datagrams at `hz`, from its own thread and socket so a
// frame never delays a force, to the address the session's stylus data last came from (the
// endpoint tells it: SetDestination).
//
// Threads: one sender thread; Add, Remove and SetDestination from any thread (a short mutex the
// sender thread also takes once per tick).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "common/core/expected.h"
#include "proto/wire/asio.h"
#include "proto/wire/datagram.h"

namespace vsurg::sim {
class Simulation;
}

namespace vsurg::server {

class VisualSender {
 public:
  // Binds a socket on `address` (any port) and starts the thread.
  static Expected<std::unique_ptr<VisualSender>> Create(const boost::asio::ip::address& address,
                                                        double hz);
  ~VisualSender();  // stops and joins
  // The simulation must outlive the session's Remove.
  void Add(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation);
  void Remove(uint64_t id);
  void SetDestination(uint64_t id, const boost::asio::ip::udp::endpoint& dest);
  uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }
  uint64_t chunks() const { return chunks_.load(std::memory_order_relaxed); }

 private:
  struct Session {
    uint64_t id;
    wire::Authenticator auth;
    sim::Simulation* simulation;
    boost::asio::ip::udp::endpoint dest;
    bool has_dest = false;
    uint64_t sequence = 0;
  };
  explicit VisualSender(double hz) : hz_(hz) {}
  void Loop();

  double hz_;
  std::mutex mutex_;  // sessions_
  std::vector<Session> sessions_;
  boost::asio::io_context io_;
  boost::asio::ip::udp::socket socket_{io_};
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> frames_{0}, chunks_{0};
};

}  // namespace vsurg::server
