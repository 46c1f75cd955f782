#include "server/net/visual_sender.h"

#include <algorithm>
#include <chrono>

#include "common/core/realtime.h"
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
  v->thread_ = std::thread([p] {
    NameThisThread("vsurg-visual");
    p->Loop();
  });
  return v;
}

VisualSender::~VisualSender() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void VisualSender::Add(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(sessions_, [id](const Session& s) { return s.id == id; });
  Session s{
      id, wire::Authenticator(key), simulation, {}, false, 0, 0, {}, {}, 0, 0, std::nullopt, 0, 0,
      {}};
  sessions_.push_back(std::move(s));
}

void VisualSender::Remove(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::erase_if(sessions_, [id](const Session& s) { return s.id == id; });
}

void VisualSender::SetDestination(uint64_t id, const udp::endpoint& dest,
                                  uint64_t twist_shape_key) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Session& s : sessions_)
    if (s.id == id) s.dest = dest, s.has_dest = true, s.shape_key = twist_shape_key;
}

void VisualSender::Loop() {
  using SteadyTime = std::chrono::steady_clock;
  sim::VisualFrame frame;
  const auto period =
      std::chrono::duration_cast<SteadyTime::duration>(std::chrono::duration<double>(1.0 / hz_));
  constexpr auto kTick = std::chrono::milliseconds(1);
  auto next_frame = SteadyTime::now();
  while (!stop_.load()) {
    const auto now = SteadyTime::now();
    const bool frame_due = now >= next_frame;
    bool queued = false;  // a chunk is left for the next tick
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (Session& s : sessions_) {
        // A new frame only when the last has all gone out (else it waits: nothing is lost).
        if (frame_due && s.next == s.sizes.size() && s.has_dest &&
            s.simulation->TakeVisualFrame(frame, s.shape_key))
          QueueFrame(s, frame, now);
        if (frame_due && s.next == s.sizes.size() && s.has_dest) RepeatTwist(s, now);
        SendShare(s);
        queued = queued || s.next < s.sizes.size();
      }
    }
    if (frame_due) {
      next_frame += period;
      if (now - next_frame > std::chrono::milliseconds(100)) next_frame = now;  // fell behind
    }
    // The next tick while chunks wait, else the next frame.
    std::this_thread::sleep_until(queued ? std::min(now + kTick, next_frame) : next_frame);
  }
}

// A new frame: a coil limb's twist as one chunk, else its moved vertices in as many as they take.
void VisualSender::QueueFrame(Session& s, const sim::VisualFrame& frame,
                              std::chrono::steady_clock::time_point now) {
  if (frame.twist && frame.twist->key == s.shape_key) {
    s.twist = wire::CoilTwist{frame.twist->key, frame.twist->grasp, frame.twist->arc,
                              frame.twist->torque};
    s.twist_frame = frame.frame_id;
    s.twist_repeats = kTwistRepeats;
    s.twist_due = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(kTwistRepeatS));
    QueueTwist(s, frame.frame_id);
    return;
  }
  if (frame.indices.empty() && frame.faces.empty()) return;
  s.twist.reset();  // vertices from now on (a surface not made by a twist)
  s.queued.clear();
  s.sizes.clear();
  s.next = 0;
  const auto sink = [&](std::span<const uint8_t> d) {
    s.queued.insert(s.queued.end(), d.begin(), d.end());
    s.sizes.push_back(static_cast<uint16_t>(d.size()));
  };
  wire::Header base{wire::kProtocolVersion, wire::PayloadType::kSceneFrame, s.id, s.sequence + 1};
  size_t chunks = codec_.EncodeSceneFrame({frame.frame_id, frame.indices, frame.positions}, base,
                                          s.auth, out_, sink);
  // A cut's faces after the vertices, so the copies a face uses have usually arrived before it.
  base.sequence += chunks;
  chunks += codec_.EncodeTopologyFrame(
      {frame.frame_id, frame.topology, frame.face_indices, frame.faces}, base, s.auth, out_, sink);
  s.sequence += chunks;
  s.per_tick = std::max<size_t>(kMinPerTick, (chunks + kSpreadMs - 1) / kSpreadMs);
  frames_.fetch_add(1, std::memory_order_relaxed);
}

// The last twist again, when it is due and repeats are owed: nothing newer came since.
void VisualSender::RepeatTwist(Session& s, std::chrono::steady_clock::time_point now) {
  if (!s.twist || s.twist_repeats <= 0 || now < s.twist_due) return;
  --s.twist_repeats;
  s.twist_due = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                          std::chrono::duration<double>(kTwistRepeatS));
  QueueTwist(s, s.twist_frame);
}

void VisualSender::QueueTwist(Session& s, uint64_t frame_id) {
  s.queued.clear();
  s.sizes.clear();
  s.next = 0;
  const wire::Header h{wire::kProtocolVersion, wire::PayloadType::kSceneFrame, s.id,
                       s.sequence + 1};
  const size_t n = codec_.EncodeTwistFrame(frame_id, *s.twist, h, s.auth, out_);
  if (n == 0) return;
  s.queued.assign(out_.begin(), out_.begin() + static_cast<ptrdiff_t>(n));
  s.sizes.push_back(static_cast<uint16_t>(n));
  s.sequence += 1;
  s.per_tick = kMinPerTick;
  frames_.fetch_add(1, std::memory_order_relaxed);
}

// This tick's share of the frame going out.
void VisualSender::SendShare(Session& s) {
  size_t sent = 0, offset = 0;
  for (size_t k = 0; k < s.next; ++k) offset += s.sizes[k];
  const size_t from = offset;
  while (s.next < s.sizes.size() && sent < s.per_tick) {
    boost::system::error_code ec;
    if (s.has_dest)
      socket_.send_to(boost::asio::buffer(s.queued.data() + offset, s.sizes[s.next]), s.dest, 0,
                      ec);
    offset += s.sizes[s.next];
    ++s.next;
    ++sent;
  }
  if (sent > 0) {
    chunks_.fetch_add(sent, std::memory_order_relaxed);
    bytes_.fetch_add(offset - from, std::memory_order_relaxed);
    if (sent > largest_burst_.load(std::memory_order_relaxed))
      largest_burst_.store(sent, std::memory_order_relaxed);
  }
}

}  // namespace vsurg::server
