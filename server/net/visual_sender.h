// The visual half of the UDP endpoint: each session's moved vertices (Simulation::
// TakeVisualFrame) sealed into SceneFrame datagrams at `hz`, from its own thread and socket so a
// frame never delays a force, to the address the session's stylus data last came from (the
// endpoint tells it: SetDestination).
//
// Paced: a frame's chunks go out over up to kSpreadMs milliseconds, at most a kSpreadMs-th of
// them (and at least kMinPerTick) each millisecond, not in one burst. A twisted arm moves nearly
// every vertex, some 60 chunks of 1,200 bytes a frame; sent at once they would sit in the
// station's socket (and on a real link, in its queue) ahead of the force answers that follow.
// A session whose frame has not all gone out when the next is due takes no new frame until it
// has: TakeVisualFrame then gives every vertex moved since, so nothing is lost, only merged.
//
// A limb twisted by the coil-spring model goes out as its twist (one chunk of three numbers,
// SceneFrame.coil_twist) instead of its moved vertices. Each such frame is whole, so the last
// one is sent again kTwistRepeats times, kTwistRepeatS apart, after the limb stops changing: a
// lost one leaves a station's view behind by at most that long.
//
// Threads: one sender thread; Add, Remove and SetDestination from any thread (a short mutex the
// sender thread also takes once per tick).
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "common/core/expected.h"
#include "proto/wire/asio.h"
#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"

namespace vsurg::sim {
class Simulation;
struct VisualFrame;
}  // namespace vsurg::sim

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
  // Where the session's frames go, and the coil limb that station remakes twists of (0: none;
  // only a frame of that key goes out as a twist, any other as vertices).
  void SetDestination(uint64_t id, const boost::asio::ip::udp::endpoint& dest,
                      uint64_t twist_shape_key = 0);
  uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }
  uint64_t chunks() const { return chunks_.load(std::memory_order_relaxed); }
  uint64_t bytes() const { return bytes_.load(std::memory_order_relaxed); }  // of those chunks
  // The most chunks one session was sent in one millisecond's tick, so far.
  uint64_t largest_burst() const { return largest_burst_.load(std::memory_order_relaxed); }

  static constexpr int kSpreadMs = 8;    // a frame's chunks go out over at most this long
  static constexpr int kMinPerTick = 2;  // chunks a session may be sent per tick, at least
  static constexpr int kTwistRepeats = 5;
  static constexpr double kTwistRepeatS = 0.2;

 private:
  struct Session {
    uint64_t id;
    wire::Authenticator auth;
    sim::Simulation* simulation;
    boost::asio::ip::udp::endpoint dest;
    bool has_dest = false;
    uint64_t shape_key = 0;  // the station's coil limb (SetDestination)
    uint64_t sequence = 0;
    // The frame going out: its sealed chunks back to back, each one's size, the next to send
    // and how many a tick may send. Kept between frames: no allocation once grown.
    std::vector<uint8_t> queued;
    std::vector<uint16_t> sizes;
    size_t next = 0;
    size_t per_tick = 0;
    // The last twist frame (when the last frame was one), and the repeats still owed after it.
    std::optional<wire::CoilTwist> twist;
    uint64_t twist_frame = 0;
    int twist_repeats = 0;
    std::chrono::steady_clock::time_point twist_due;
  };
  explicit VisualSender(double hz) : hz_(hz) {}
  void Loop();
  // The stages of one tick for one session: a new frame queued (vertices or a twist), the last
  // twist queued again when due, this tick's share of the queue sent.
  void QueueFrame(Session& s, const sim::VisualFrame& frame,
                  std::chrono::steady_clock::time_point now);
  void RepeatTwist(Session& s, std::chrono::steady_clock::time_point now);
  void QueueTwist(Session& s, uint64_t frame_id);
  void SendShare(Session& s);

  double hz_;
  wire::Codec codec_;  // the sender thread's
  std::array<uint8_t, wire::kMaxDatagram> out_{};
  std::mutex mutex_;  // sessions_
  std::vector<Session> sessions_;
  boost::asio::io_context io_;
  boost::asio::ip::udp::socket socket_{io_};
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> frames_{0}, chunks_{0}, bytes_{0}, largest_burst_{0};
};

}  // namespace vsurg::server
