#include "server/net/visual_sender.h"

#include <algorithm>
#include <chrono>

#include "common/sim/simulation.h"
#include "proto/wire/messages.h"

namespace vsurg::server {

namespace asio = boost::asio;
using asio::ip::udp;

Expected<std::unique_ptr<VisualSender>> VisualSender::Create(const asio::ip::address& address,
                                                             double hz) {
  std::unique_ptr<VisualSender> v(new VisualSender(hz));
  boost::system::error_code ec;
  v->socket_.open(address.is_v6() ? udp::v6() : udp::v4(), ec);
  if (!ec) v->socket_.bind(udp::endpoint(address, 0), ec);
  if (ec) return Error{ErrorCode::kIoError, "cannot bind the visual socket: " + ec.message(), ""};
  VisualSender* p = v.get();
  v->thread_ = std::thread([p] { p->Loop(); });
  return v;
}

VisualSender::~VisualSender() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void VisualSender::Add(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(sessions_, [id](const Session& s) { return s.id == id; });
  sessions_.push_back({id, wire::Authenticator(key), simulation, {}, false, 0});
}

void VisualSender::Remove(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(sessions_, [id](const Session& s) { return s.id == id; });
}

void VisualSender::SetDestination(uint64_t id, const udp::endpoint& dest) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Session& s : sessions_)
    if (s.id == id) s.dest = dest, s.has_dest = true;
}

void VisualSender::Loop() {
  using SteadyTime = std::chrono::steady_clock;
  sim::VisualFrame frame;
  wire::Codec codec;
  std::array<uint8_t, wire::kMaxDatagram> out{};
  const auto period =
      std::chrono::duration_cast<SteadyTime::duration>(std::chrono::duration<double>(1.0 / hz_));
  auto next = SteadyTime::now();
  while (!stop_.load()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (Session& s : sessions_) {
        if (!s.has_dest || !s.simulation->TakeVisualFrame(frame) || frame.indices.empty()) continue;
        const wire::Header base{wire::kProtocolVersion, wire::PayloadType::kSceneFrame, s.id,
                                s.sequence + 1};
        const size_t chunks = codec.EncodeSceneFrame(
            {frame.frame_id, frame.indices, frame.positions}, base, s.auth, out,
            [&](std::span<const uint8_t> d) {
              boost::system::error_code ec;
              socket_.send_to(asio::buffer(d.data(), d.size()), s.dest, 0, ec);
            });
        s.sequence += chunks;
        frames_.fetch_add(1, std::memory_order_relaxed);
        chunks_.fetch_add(chunks, std::memory_order_relaxed);
      }
    }
    next += period;
    std::this_thread::sleep_until(next);
  }
}

}  // namespace vsurg::server
