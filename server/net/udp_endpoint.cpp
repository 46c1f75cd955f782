#include "server/net/udp_endpoint.h"

#include <time.h>

#include <chrono>
#include <future>
#include <unordered_map>

#include "common/core/realtime.h"
#include "common/sim/simulation.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"
#include "server/net/visual_sender.h"

namespace vsurg::server {

namespace asio = boost::asio;
using asio::ip::udp;

struct UdpEndpoint::Impl {
  struct Session {
    Session(const wire::SessionKey& key, sim::Simulation* sim, LinkStats* stats,
            double tokens_at_start, double now)
        : auth(key),
          simulation(sim),
          link(stats),
          last_seen(now),
          tokens(tokens_at_start),
          refill(now) {}
    wire::Authenticator auth;
    sim::Simulation* simulation = nullptr;
    LinkStats* link = nullptr;
    uint64_t last_sequence = 0;
    uint64_t sent_sequence = 0;
    double last_seen;  // s, the endpoint's clock
    bool seen = false;
    SessionState state = SessionState::kRunning;
    double tokens = 0;
    double refill;  // s
    udp::endpoint source;
  };

  EndpointOptions options;
  asio::io_context io;
  udp::socket socket{io};
  asio::steady_timer timer{io};
  std::thread thread;
  const Clock* clock = &DefaultClock();  // options.clock when given
  double start = 0;
  std::unordered_map<uint64_t, Session> sessions;  // I/O thread only
  std::array<uint8_t, wire::kMaxDatagram + 1> rx{};
  std::array<uint8_t, wire::kMaxDatagram> tx{};
  udp::endpoint sender;
  wire::Codec codec;
  wire::StylusMessage stylus;
  wire::ForceMessage force;

  std::atomic<uint64_t> received{0}, answered{0};
  std::array<std::atomic<uint64_t>, static_cast<size_t>(wire::DropReason::kCount)> dropped{};
  std::atomic<double> io_cpu{0};

  std::unique_ptr<VisualSender> visual;  // null when visual_hz is 0
  std::mutex events_mutex;
  std::vector<SessionEvent> events;

  double Now() const { return clock->Now() - start; }

  void Drop(wire::DropReason r) {
    dropped[static_cast<size_t>(r)].fetch_add(1, std::memory_order_relaxed);
  }

  void Record(uint64_t id, SessionState state) {
    std::lock_guard<std::mutex> lock(events_mutex);  // control-plane side; not on the force path
    events.push_back({id, state, Now()});
  }

  void Receive() {
    socket.async_receive_from(asio::buffer(rx), sender,
                              [this](const boost::system::error_code& ec, size_t n) {
                                if (ec == asio::error::operation_aborted) return;
                                if (!ec) Handle(n);
                                Receive();
                              });
  }

  void Handle(size_t n) {
    received.fetch_add(1, std::memory_order_relaxed);
    const std::span<const uint8_t> d(rx.data(), n);
    wire::Header header;
    if (const wire::DropReason r = wire::PeekHeader(d, header); r != wire::DropReason::kNone)
      return Drop(r);
    if (header.type != wire::PayloadType::kStylusState) return Drop(wire::DropReason::kBadType);
    const auto it = sessions.find(header.session);
    if (it == sessions.end()) return Drop(wire::DropReason::kUnknownSession);
    Session& s = it->second;
    std::span<const uint8_t> payload;  // the header was parsed once, above
    if (const wire::DropReason r = wire::Verify(d, s.auth, payload); r != wire::DropReason::kNone)
      return Drop(r);
    if (s.seen && header.sequence <= s.last_sequence) return Drop(wire::DropReason::kStale);
    const double now = Now();
    // Token bucket: max_packets_per_s, bursts of a tenth of a second.
    s.tokens = std::min(options.max_packets_per_s * 0.1,
                        s.tokens + options.max_packets_per_s * std::max(0.0, now - s.refill));
    s.refill = now;
    if (s.tokens < 1.0) return Drop(wire::DropReason::kRateLimited);
    s.tokens -= 1.0;
    if (const wire::DropReason r = codec.DecodeStylus(payload, stylus);
        r != wire::DropReason::kNone)
      return Drop(r);
    if (s.link) {
      if (s.seen && header.sequence > s.last_sequence + 1)
        s.link->lost.fetch_add(header.sequence - s.last_sequence - 1, std::memory_order_relaxed);
      s.link->applied.fetch_add(1, std::memory_order_relaxed);
      if (stylus.rtt_us > 0) s.link->rtt_us.store(stylus.rtt_us, std::memory_order_relaxed);
      s.link->last_seen_s.store(now, std::memory_order_relaxed);
    }
    s.last_sequence = header.sequence;
    s.last_seen = now;
    s.seen = true;
    if (sender != s.source) {  // first datagram, or the station moved (NAT rebinding): rare
      s.source = sender;
      if (visual) visual->SetDestination(header.session, sender);
    }
    if (s.state != SessionState::kRunning) {
      s.state = SessionState::kRunning;
      Record(header.session, SessionState::kRunning);
    }
    force.command = s.simulation->OnStylus(stylus.sample);
    force.echo_sequence = header.sequence;
    force.echo_time = stylus.sample.time;
    force.server_time = now;
    const wire::Header out{wire::kProtocolVersion, wire::PayloadType::kForceFeedback,
                           header.session, ++s.sent_sequence};
    const size_t size = codec.EncodeForce(force, out, s.auth, tx);
    if (size == 0) return;
    boost::system::error_code ec;
    socket.send_to(asio::buffer(tx.data(), size), sender, 0, ec);
    if (!ec) answered.fetch_add(1, std::memory_order_relaxed);
  }

  void Tick() {
    timer.expires_after(std::chrono::milliseconds(50));
    timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      timespec cpu{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu);
      io_cpu.store(static_cast<double>(cpu.tv_sec) + 1e-9 * static_cast<double>(cpu.tv_nsec));
      CheckTimeouts();
      Tick();
    });
  }

  // Running → stalled → disconnected by the endpoint's clock. I/O thread.
  void CheckTimeouts() {
    const double now = Now();
    for (auto& [id, s] : sessions) {
      const double quiet = now - s.last_seen;
      SessionState next = s.state;
      if (quiet > options.disconnect_after_s) {
        next = SessionState::kDisconnected;
      } else if (quiet > options.stall_after_s) {
        next = SessionState::kStalled;
      }
      if (next != s.state &&
          (next == SessionState::kDisconnected || s.state == SessionState::kRunning)) {
        s.state = next;
        Record(id, next);
      }
    }
  }
};

Expected<std::unique_ptr<UdpEndpoint>> UdpEndpoint::Create(const EndpointOptions& options) {
  if (!(options.stall_after_s > 0 && options.disconnect_after_s > options.stall_after_s)) {
    return InvalidArgument("timeouts", "need 0 < stall_after_s < disconnect_after_s");
  }
  if (!(options.max_packets_per_s >= 10))
    return InvalidArgument("max_packets_per_s", "must be ≥ 10");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  if (options.clock) impl->clock = options.clock;
  impl->start = impl->clock->Now();
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options.address, ec);
  if (ec) return InvalidArgument("address", "'" + options.address + "' is not an IP address");
  impl->socket.open(address.is_v6() ? udp::v6() : udp::v4(), ec);
  if (!ec) impl->socket.bind(udp::endpoint(address, options.port), ec);
  if (ec) {
    return Error{ErrorCode::kIoError,
                 "cannot bind UDP " + options.address + ":" + std::to_string(options.port) + ": " +
                     ec.message(),
                 "port"};
  }
  impl->sessions.reserve(1024);
  // The visual sender exists before the I/O thread starts and outlives it (Stop): the I/O thread
  // reads the pointer on every new source address without a lock.
  if (options.visual_hz > 0) {
    auto visual = VisualSender::Create(address, options.visual_hz);
    if (visual.ok()) impl->visual = std::move(visual).value();  // else: forces only, no frames
  }
  Impl* p = impl.get();
  p->Receive();
  p->Tick();
  p->thread = std::thread([p] {
    TrySetRealtimePriority(p->options.realtime_priority);  // the stylus → force path
    p->io.run();
  });
  return std::unique_ptr<UdpEndpoint>(new UdpEndpoint(std::move(impl)));
}

UdpEndpoint::UdpEndpoint(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

UdpEndpoint::~UdpEndpoint() {
  Stop();
}

uint16_t UdpEndpoint::port() const {
  boost::system::error_code ec;
  return impl_->socket.local_endpoint(ec).port();
}

void UdpEndpoint::AddSession(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation,
                             LinkStats* link) {
  std::promise<void> done;
  asio::post(impl_->io, [this, id, key, simulation, link, &done] {
    impl_->sessions.insert_or_assign(
        id,
        Impl::Session(key, simulation, link, impl_->options.max_packets_per_s * 0.1, impl_->Now()));
    if (impl_->visual) impl_->visual->Add(id, key, simulation);
    done.set_value();
  });
  if (impl_->thread.joinable()) done.get_future().wait();
}

void UdpEndpoint::RemoveSession(uint64_t id) {
  std::promise<void> done;
  asio::post(impl_->io, [this, id, &done] {
    impl_->sessions.erase(id);
    if (impl_->visual) impl_->visual->Remove(id);
    done.set_value();
  });
  if (impl_->thread.joinable()) done.get_future().wait();
}

void UdpEndpoint::Stop() {
  if (!impl_) return;
  if (!impl_->thread.joinable()) {
    impl_->visual.reset();  // stops and joins the sender thread
    return;
  }
  asio::post(impl_->io, [p = impl_.get()] {
    boost::system::error_code ec;
    p->timer.cancel();
    p->socket.close(ec);
    // A timer that had already fired is not cancelled: its handler would re-arm it and run()
    // would never run out of work. Stop the loop outright.
    p->io.stop();
  });
  impl_->thread.join();
  impl_->visual.reset();  // after the I/O thread, the sender's one reader, has ended
}

EndpointCounters UdpEndpoint::counters() const {
  EndpointCounters c;
  c.received = impl_->received.load();
  c.answered = impl_->answered.load();
  c.frames = impl_->visual ? impl_->visual->frames() : 0;
  c.frame_chunks = impl_->visual ? impl_->visual->chunks() : 0;
  for (size_t i = 0; i < c.dropped.size(); ++i) c.dropped[i] = impl_->dropped[i].load();
  return c;
}

double UdpEndpoint::io_cpu_seconds() const {
  return impl_->io_cpu.load();
}

void UdpEndpoint::CheckTimeoutsNow() {
  std::promise<void> done;
  asio::post(impl_->io, [this, &done] {
    impl_->CheckTimeouts();
    done.set_value();
  });
  if (impl_->thread.joinable()) done.get_future().wait();
}

std::thread::id UdpEndpoint::io_thread_id() const {
  return impl_->thread.get_id();
}

std::vector<SessionEvent> UdpEndpoint::TakeEvents() {
  std::lock_guard<std::mutex> lock(impl_->events_mutex);
  std::vector<SessionEvent> out;
  out.swap(impl_->events);
  return out;
}

}  // namespace vsurg::server
