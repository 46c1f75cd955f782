#include "server/net/udp_endpoint.h"

#include <linux/filter.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <future>
#include <limits>
#include <unordered_map>

#include "common/core/realtime.h"
#include "common/sim/simulation.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"
#include "server/net/lease.h"
#include "server/net/visual_sender.h"

namespace vsurg::server {

namespace asio = boost::asio;
using asio::ip::udp;

// Each I/O thread (a lane) blocks in recvmmsg on its own socket (no event loop): a lone datagram
// costs two system calls, the receive and the answer's send, as the bare echo's do; under load
// one receive returns up to kBatch datagrams, and their answers leave together in one sendmmsg
// (each waits at most for the batch's other stylus samples to be handled, about a microsecond
// each). With more than one lane the sockets share the port (SO_REUSEPORT) and a classic BPF
// program attached to the group steers each datagram by its session id (AttachSteering), so a
// session is always served by the same lane, which alone owns its state: no lock on the hot
// path, and a station's answers never wait behind another lane's batch. Work from other threads
// (add and remove a session, a timeout check) is queued on the session's lane and the lane woken
// by a datagram from the endpoint's own waker socket, steered like a stylus datagram; the 50 ms
// housekeeping (timeouts, the CPU sample, whether to busy-poll) runs when a receive returns
// after its deadline, and a quiet socket returns every 50 ms (SO_RCVTIMEO). With busy_poll_us a
// lane polls before it blocks, while its datagrams come fast (EndpointOptions::busy_poll_us).
namespace {

// The byte of a datagram that steers it: the session id's least significant byte (the id is
// little-endian at offset 4, proto/wire/datagram.h). Sessions are numbered consecutively, so
// `byte mod lanes` spreads them evenly.
constexpr uint32_t kSteeringOffset = 4;
static_assert(wire::kHeaderSize > kSteeringOffset);

int LaneOfId(uint64_t id, int lanes) {
  return static_cast<int>((id & 0xff) % static_cast<uint64_t>(lanes));
}

// The reuseport group's program: index = datagram[4] mod lanes. The kernel runs it on the UDP
// payload; a datagram too short to hold the byte ends the program with 0 (lane 0, which drops
// it as malformed).
Status AttachSteering(int fd, int lanes) {
  sock_filter code[] = {
      {BPF_LD | BPF_B | BPF_ABS, 0, 0, kSteeringOffset},
      {BPF_ALU | BPF_MOD | BPF_K, 0, 0, static_cast<uint32_t>(lanes)},
      {BPF_RET | BPF_A, 0, 0, 0},
  };
  sock_fprog program{static_cast<unsigned short>(std::size(code)), code};
  if (::setsockopt(fd, SOL_SOCKET, SO_ATTACH_REUSEPORT_CBPF, &program, sizeof program) != 0)
    return Error{ErrorCode::kIoError,
                 std::string("cannot steer the UDP sockets by session: ") + std::strerror(errno),
                 "io_threads"};
  return {};
}

// The kernel's arrival stamp of a received datagram (ns, CLOCK_REALTIME); `fallback` when it
// carries none.
int64_t ArrivalNs(const msghdr& h, int64_t fallback) {
  for (const cmsghdr* c = CMSG_FIRSTHDR(&h); c;
       c = CMSG_NXTHDR(const_cast<msghdr*>(&h), const_cast<cmsghdr*>(c))) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS) continue;
    timespec t{};
    std::memcpy(&t, CMSG_DATA(c), sizeof t);
    return static_cast<int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
  }
  return fallback;
}

}  // namespace

struct UdpEndpoint::Impl {
  static constexpr int kBatch = 16;
  static constexpr double kTickS = 0.05;

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
    uint64_t twist_shape_key = 0;  // the coil limb the station says it remakes (visual frames)
    double moved_until = -1;       // s; ≥ 0: moved away (no simulation): answered with a notice
    ChannelRole role = ChannelRole::kTrainee;  // whose haptic path answers it
  };

  // One I/O thread, its socket and the sessions steered to it. Everything here but the atomics
  // and the queue is the lane's own thread's.
  struct Lane {
    Impl* owner = nullptr;
    int index = 0;
    udp::socket socket;
    std::thread thread;
    std::unordered_map<uint64_t, Session> sessions;
    std::array<std::array<uint8_t, wire::kMaxDatagram + 1>, kBatch> rx{};
    std::array<udp::endpoint, kBatch> senders;
    std::array<iovec, kBatch> iov{};
    std::array<mmsghdr, kBatch> headers{};
    // Each datagram's control message: its kernel arrival stamp (SO_TIMESTAMPNS, CLOCK_REALTIME).
    static constexpr size_t kControlSize = CMSG_SPACE(sizeof(timespec));
    std::array<std::array<uint8_t, kControlSize>, kBatch> control{};
    // The batch's answers, sent together by Flush.
    std::array<std::array<uint8_t, wire::kMaxDatagram>, kBatch> out_data{};
    std::array<udp::endpoint, kBatch> out_to;
    std::array<iovec, kBatch> out_iov{};
    std::array<mmsghdr, kBatch> out_headers{};
    std::array<int64_t, kBatch> out_arrival_ns{};  // each answer's datagram's arrival stamp
    int out_count = 0;
    wire::Codec codec;
    wire::StylusMessage stylus;
    wire::ForceMessage force;

    std::mutex pending_mutex;
    std::vector<std::function<void()>> pending;  // run on this lane's thread, in order
    std::atomic<bool> has_pending{false};

    std::atomic<uint64_t> received{0}, answered{0}, busy_polls{0}, busy_polled{0};
    std::array<std::atomic<uint64_t>, EndpointCounters::kResidenceBounds.size() + 1> residence{};
    std::atomic<int64_t> residence_ns{0};
    // Busy polling (EndpointOptions::busy_poll_us): on while the last tick's datagrams came at
    // least one per window; set at each housekeeping tick.
    bool poll = false;
    uint64_t received_at_tick = 0;
    std::array<std::atomic<uint64_t>, static_cast<size_t>(wire::DropReason::kCount)> dropped{};
    std::atomic<double> io_cpu{0};

    Lane(Impl* impl, int i) : owner(impl), index(i), socket(impl->io) {}

    void Drop(wire::DropReason r) {
      dropped[static_cast<size_t>(r)].fetch_add(1, std::memory_order_relaxed);
    }

    // Any thread: runs `fn` on this lane's thread and waits for it (at once when the thread has
    // not started or has ended).
    void Run(std::function<void()> fn) {
      if (!thread.joinable() || std::this_thread::get_id() == thread.get_id()) return fn();
      std::promise<void> done;
      {
        std::lock_guard<std::mutex> lock(pending_mutex);
        pending.push_back([&] {
          fn();
          done.set_value();
        });
        has_pending.store(true, std::memory_order_release);
      }
      owner->Wake(index);
      done.get_future().wait();
    }

    void RunPending() {
      std::vector<std::function<void()>> work;
      {
        std::lock_guard<std::mutex> lock(pending_mutex);
        work.swap(pending);
        has_pending.store(false, std::memory_order_relaxed);
      }
      for (auto& fn : work) fn();
    }

    void Loop();
    void Handle(int slot, size_t n, int64_t arrival_ns, int64_t age_ns);
    void Flush();
    void CheckTimeouts();
  };

  EndpointOptions options;
  asio::io_context io;  // owns the sockets; never run
  std::vector<std::unique_ptr<Lane>> lanes;
  udp::socket waker{io};  // sends the datagrams that wake a lane
  udp::endpoint waker_address;
  // The port's one holder: an abstract Unix socket named after the address and port (freed by
  // the kernel when the process ends). With SO_REUSEPORT a second endpoint could otherwise join
  // the port's group and take a share of its datagrams; this way it is refused, as a plain bind
  // would be.
  int port_lock = -1;
  const Clock* clock = &DefaultClock();  // options.clock when given
  double start = 0;
  int64_t max_age_ns = 0;
  std::atomic<bool> stop{false};

  std::unique_ptr<VisualSender> visual;  // null when visual_hz is 0
  std::mutex events_mutex;
  std::vector<SessionEvent> events;

  ~Impl() {
    if (port_lock >= 0) ::close(port_lock);
  }

  double Now() const { return clock->Now() - start; }
  Lane& LaneOf(uint64_t id) { return *lanes[LaneOfId(id, static_cast<int>(lanes.size()))]; }

  void Record(uint64_t id, SessionState state) {
    std::lock_guard<std::mutex> lock(events_mutex);  // control-plane side; not on the force path
    events.push_back({id, state, Now()});
  }

  // A datagram from the waker, steered to `lane` (its steering byte is the lane's index): the
  // lane's receive returns and it runs its queue. Recognised by its source, whatever its size.
  void Wake(int lane) {
    std::array<uint8_t, kSteeringOffset + 1> wake{};
    wake[kSteeringOffset] = static_cast<uint8_t>(lane);
    boost::system::error_code ec;
    waker.send(asio::buffer(wake), 0, ec);
  }
};

void UdpEndpoint::Impl::Lane::Loop() {
  const EndpointOptions& opts = owner->options;
  NameThisThread(("vsurg-io/" + std::to_string(index)).c_str());
  TrySetRealtimePriority(opts.realtime_priority);  // the stylus → force path
  const int fd = socket.native_handle();
  const std::chrono::microseconds busy_poll(opts.busy_poll_us);
  for (int i = 0; i < kBatch; ++i) {
    iov[i] = {rx[i].data(), rx[i].size()};
    headers[i].msg_hdr.msg_iov = &iov[i];
    headers[i].msg_hdr.msg_iovlen = 1;
  }
  auto next_tick = std::chrono::steady_clock::now();
  while (!owner->stop.load(std::memory_order_acquire)) {
    if (has_pending.load(std::memory_order_acquire)) RunPending();
    for (int i = 0; i < kBatch; ++i) {
      headers[i].msg_hdr.msg_name = senders[i].data();
      headers[i].msg_hdr.msg_namelen = static_cast<socklen_t>(senders[i].capacity());
      headers[i].msg_hdr.msg_control = control[i].data();
      headers[i].msg_hdr.msg_controllen = kControlSize;
    }
    int n = -1;
    if (poll) {
      // Poll for up to the window, then block as usual; queued work and a stop are not kept
      // waiting for the window's end.
      busy_polls.fetch_add(1, std::memory_order_relaxed);
      const auto until = std::chrono::steady_clock::now() + busy_poll;
      do {
        n = ::recvmmsg(fd, headers.data(), kBatch, MSG_DONTWAIT, nullptr);
      } while (n <= 0 && !has_pending.load(std::memory_order_relaxed) &&
               !owner->stop.load(std::memory_order_relaxed) &&
               std::chrono::steady_clock::now() < until);
      if (n > 0) busy_polled.fetch_add(1, std::memory_order_relaxed);
    }
    if (n <= 0 && (has_pending.load(std::memory_order_acquire) ||
                   owner->stop.load(std::memory_order_acquire)))
      continue;
    if (n <= 0) n = ::recvmmsg(fd, headers.data(), kBatch, MSG_WAITFORONE, nullptr);
    timespec wall{};
    if (n > 0) clock_gettime(CLOCK_REALTIME, &wall);
    const int64_t read_ns = static_cast<int64_t>(wall.tv_sec) * 1'000'000'000 + wall.tv_nsec;
    for (int i = 0; i < n; ++i) {
      senders[i].resize(headers[i].msg_hdr.msg_namelen);
      if (senders[i] == owner->waker_address) continue;  // a wake-up, not traffic
      const int64_t arrival_ns = ArrivalNs(headers[i].msg_hdr, read_ns);
      Handle(i, headers[i].msg_len, arrival_ns, read_ns - arrival_ns);
    }
    Flush();
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_tick) {
      // The rate over the tick just ended decides whether the next one polls: on when a datagram
      // came at least once per window on average.
      const uint64_t count = received.load(std::memory_order_relaxed);
      const double elapsed = kTickS + std::chrono::duration<double>(now - next_tick).count();
      poll = busy_poll.count() > 0 && static_cast<double>(count - received_at_tick) *
                                              std::chrono::duration<double>(busy_poll).count() >=
                                          elapsed;
      received_at_tick = count;
      next_tick = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(kTickS));
      timespec cpu{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu);
      io_cpu.store(static_cast<double>(cpu.tv_sec) + 1e-9 * static_cast<double>(cpu.tv_nsec));
      CheckTimeouts();
    }
  }
  RunPending();  // whoever waits on a queued call is not left waiting
}

// `arrival_ns`: the datagram's arrival stamp (CLOCK_REALTIME); `age_ns`: how long it waited in
// the receive queue (negative when the wall clock was stepped back meanwhile: taken as fresh).
void UdpEndpoint::Impl::Lane::Handle(int slot, size_t n, int64_t arrival_ns, int64_t age_ns) {
  const EndpointOptions& opts = owner->options;
  received.fetch_add(1, std::memory_order_relaxed);
  const std::span<const uint8_t> d(rx[slot].data(), n);
  const udp::endpoint& sender = senders[slot];
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
  if (age_ns > owner->max_age_ns) return Drop(wire::DropReason::kLate);
  if (opts.lease && !opts.lease->Valid()) return Drop(wire::DropReason::kFenced);
  const double now = owner->Now();
  // Token bucket: max_packets_per_s, bursts of a tenth of a second.
  s.tokens = std::min(opts.max_packets_per_s * 0.1,
                      s.tokens + opts.max_packets_per_s * std::max(0.0, now - s.refill));
  s.refill = now;
  if (s.tokens < 1.0) return Drop(wire::DropReason::kRateLimited);
  s.tokens -= 1.0;
  if (const wire::DropReason r = codec.DecodeStylus(payload, stylus); r != wire::DropReason::kNone)
    return Drop(r);
  if (s.link) {
    if (s.seen && header.sequence > s.last_sequence + 1)
      s.link->lost.fetch_add(header.sequence - s.last_sequence - 1, std::memory_order_relaxed);
    s.link->applied.fetch_add(1, std::memory_order_relaxed);
    if (stylus.rtt_us > 0) s.link->rtt_us.store(stylus.rtt_us, std::memory_order_relaxed);
    // The station's figures only grow within a session: a reordered datagram cannot lower them.
    if (stylus.rendered_peak_n > s.link->rendered_peak_n.load(std::memory_order_relaxed))
      s.link->rendered_peak_n.store(stylus.rendered_peak_n, std::memory_order_relaxed);
    if (stylus.rendered_over_limit_s >
        s.link->rendered_over_limit_s.load(std::memory_order_relaxed))
      s.link->rendered_over_limit_s.store(stylus.rendered_over_limit_s, std::memory_order_relaxed);
    if (stylus.jitter_us > 0) s.link->jitter_us.store(stylus.jitter_us, std::memory_order_relaxed);
    if (s.link->first_seen_s.load(std::memory_order_relaxed) < 0)
      s.link->first_seen_s.store(now, std::memory_order_relaxed);
    s.link->last_seen_s.store(now, std::memory_order_relaxed);
  }
  s.last_sequence = header.sequence;
  s.last_seen = now;
  s.seen = true;
  if (sender != s.source || stylus.twist_shape_key != s.twist_shape_key) {
    // First datagram, the station moved (NAT rebinding) or says another limb: rare.
    s.source = sender;
    s.twist_shape_key = stylus.twist_shape_key;
    if (owner->visual && s.moved_until < 0 && s.role == ChannelRole::kTrainee)
      owner->visual->SetDestination(header.session, sender, stylus.twist_shape_key);
  }
  if (s.moved_until >= 0) {  // moved away: say so, compute nothing
    force.command = haptics::ForceCommand{};
    force.command.time = std::isfinite(stylus.sample.time) ? stylus.sample.time : 0;
    force.command.events = haptics::kEventSessionMoved;
  } else {
    if (s.state != SessionState::kRunning) {
      s.state = SessionState::kRunning;
      if (s.role == ChannelRole::kTrainee) owner->Record(header.session, SessionState::kRunning);
    }
    force.command = s.role == ChannelRole::kTrainee ? s.simulation->OnStylus(stylus.sample)
                    : s.role == ChannelRole::kInstructor
                        ? s.simulation->OnInstructorStylus(stylus.sample)
                        : s.simulation->OnSecondHandStylus(stylus.sample);
  }
  force.echo_sequence = header.sequence;
  force.echo_time = stylus.sample.time;
  force.server_time = now;
  const wire::Header out{wire::kProtocolVersion, wire::PayloadType::kForceFeedback, header.session,
                         ++s.sent_sequence};
  const size_t size = codec.EncodeForce(force, out, s.auth, out_data[out_count]);
  if (size == 0) return;
  out_iov[out_count] = {out_data[out_count].data(), size};
  out_to[out_count] = sender;
  out_arrival_ns[out_count] = arrival_ns;
  ++out_count;  // one answer per received datagram: at most kBatch
}

// The batch's answers in one system call. One the kernel refuses (a full buffer, a station gone)
// is skipped and the rest sent, as a lone sendto's would have been lost.
void UdpEndpoint::Impl::Lane::Flush() {
  for (int i = 0; i < out_count; ++i) {
    msghdr& h = out_headers[i].msg_hdr;
    h = {};
    h.msg_name = out_to[i].data();
    h.msg_namelen = static_cast<socklen_t>(out_to[i].size());
    h.msg_iov = &out_iov[i];
    h.msg_iovlen = 1;
  }
  for (int sent = 0; sent < out_count;) {
    const int n = ::sendmmsg(socket.native_handle(), out_headers.data() + sent,
                             static_cast<unsigned>(out_count - sent), 0);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      ++sent;  // this one failed (a station gone: ECONNREFUSED, a full buffer): skip it
      continue;
    }
    answered.fetch_add(static_cast<uint64_t>(n), std::memory_order_relaxed);
    sent += n;
  }
  // The batch's residences, by the clock the arrival stamps are on (one reading for the batch).
  if (out_count > 0) {
    timespec wall{};
    clock_gettime(CLOCK_REALTIME, &wall);
    const int64_t now_ns = static_cast<int64_t>(wall.tv_sec) * 1'000'000'000 + wall.tv_nsec;
    int64_t total = 0;
    for (int i = 0; i < out_count; ++i) {
      const int64_t ns = std::max<int64_t>(0, now_ns - out_arrival_ns[i]);  // a stepped clock: 0
      total += ns;
      const double s = 1e-9 * static_cast<double>(ns);
      const auto& bounds = EndpointCounters::kResidenceBounds;
      const size_t b =
          static_cast<size_t>(std::lower_bound(bounds.begin(), bounds.end(), s) - bounds.begin());
      residence[b].fetch_add(1, std::memory_order_relaxed);
    }
    residence_ns.fetch_add(total, std::memory_order_relaxed);
  }
  out_count = 0;
}

// Running → stalled → disconnected by the endpoint's clock, for this lane's sessions.
void UdpEndpoint::Impl::Lane::CheckTimeouts() {
  const EndpointOptions& opts = owner->options;
  const double now = owner->Now();
  std::erase_if(sessions, [now](const auto& e) {
    return e.second.moved_until >= 0 && now > e.second.moved_until;
  });
  for (auto& [id, s] : sessions) {
    // No events of a session that moved away; a second channel's silence is its hand's (the
    // simulation hands the tool back), not the session's.
    if (s.moved_until >= 0 || s.role != ChannelRole::kTrainee) continue;
    const double quiet = now - s.last_seen;
    SessionState next = s.state;
    if (quiet > opts.disconnect_after_s) {
      next = SessionState::kDisconnected;
    } else if (quiet > opts.stall_after_s) {
      next = SessionState::kStalled;
    }
    if (next != s.state &&
        (next == SessionState::kDisconnected || s.state == SessionState::kRunning)) {
      s.state = next;
      owner->Record(id, next);
    }
  }
}

Expected<std::unique_ptr<UdpEndpoint>> UdpEndpoint::Create(const EndpointOptions& options) {
  if (!(options.stall_after_s > 0 && options.disconnect_after_s > options.stall_after_s)) {
    return InvalidArgument("timeouts", "need 0 < stall_after_s < disconnect_after_s");
  }
  if (!(options.max_packets_per_s >= 10))
    return InvalidArgument("max_packets_per_s", "must be ≥ 10");
  if (!(options.max_input_age_s >= 0.001 && options.max_input_age_s <= 10))
    return InvalidArgument("max_input_age_s", "must be within 0.001..10 s");
  if (options.io_threads < 1 || options.io_threads > kMaxIoThreads)
    return InvalidArgument("io_threads", "must be within 1.." + std::to_string(kMaxIoThreads));
  if (options.busy_poll_us < 0 || options.busy_poll_us > kMaxBusyPollUs)
    return InvalidArgument("busy_poll_us", "must be within 0.." + std::to_string(kMaxBusyPollUs));
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  if (options.clock) impl->clock = options.clock;
  impl->start = impl->clock->Now();
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options.address, ec);
  if (ec) return InvalidArgument("address", "'" + options.address + "' is not an IP address");
  const bool shared = options.io_threads > 1;
  auto bind_error = [&](const std::string& why) {
    return Error{
        ErrorCode::kIoError,
        "cannot bind UDP " + options.address + ":" + std::to_string(options.port) + ": " + why,
        "port"};
  };
  uint16_t port = options.port;
  for (int i = 0; i < options.io_threads; ++i) {
    auto lane = std::make_unique<Impl::Lane>(impl.get(), i);
    udp::socket& socket = lane->socket;
    socket.open(address.is_v6() ? udp::v6() : udp::v4(), ec);
    if (ec) return bind_error(ec.message());
    const int fd = socket.native_handle();
    const int on = 1;
    if (shared && ::setsockopt(fd, SOL_SOCKET, SO_REUSEPORT, &on, sizeof on) != 0)
      return bind_error(std::string("SO_REUSEPORT: ") + std::strerror(errno));
    socket.bind(udp::endpoint(address, port), ec);
    if (ec) return bind_error(ec.message());
    if (i == 0) {
      port = socket.local_endpoint().port();  // an ephemeral port is chosen once, for all lanes
      if (shared) {
        // Held before any other lane binds: a second endpoint on this address and port is
        // refused here instead of joining the group.
        impl->port_lock = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        sockaddr_un name{};
        name.sun_family = AF_UNIX;
        const std::string id =
            "vsurg-udp-" + address.to_string() + ":" + std::to_string(port);  // abstract: \0 first
        std::memcpy(name.sun_path + 1, id.data(), std::min(id.size(), sizeof name.sun_path - 1));
        const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + 1 + id.size());
        if (impl->port_lock < 0 ||
            ::bind(impl->port_lock, reinterpret_cast<const sockaddr*>(&name), len) != 0)
          return bind_error("held by another endpoint");
      }
    }
    if (options.receive_buffer_bytes > 0) {  // best effort: the kernel may cap it
      const int bytes = options.receive_buffer_bytes;
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes);
    }
    const int stamp = 1;  // each datagram's arrival time, for the age bound
    if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &stamp, sizeof stamp) != 0)
      return Error{ErrorCode::kIoError, "cannot ask for the UDP socket's arrival stamps", "port"};
    // A quiet socket's receive returns every tick, for the housekeeping.
    const timeval tick{0, static_cast<suseconds_t>(Impl::kTickS * 1e6)};
    if (::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tick, sizeof tick) != 0)
      return Error{ErrorCode::kIoError, "cannot set the UDP socket's receive timeout", "port"};
    lane->sessions.reserve(1024);
    lane->pending.reserve(16);
    impl->lanes.push_back(std::move(lane));
  }
  if (shared) {
    if (Status steered = AttachSteering(impl->lanes[0]->socket.native_handle(), options.io_threads);
        !steered.ok())
      return steered.error();
  }
  impl->max_age_ns = static_cast<int64_t>(options.max_input_age_s * 1e9);
  // The waker: a socket on the same address (loopback when the endpoint listens on every
  // address), connected to the endpoint; its datagrams are recognised by their source.
  asio::ip::address wake_to = address;
  if (address.is_unspecified())
    wake_to = address.is_v6() ? asio::ip::address(asio::ip::address_v6::loopback())
                              : asio::ip::address(asio::ip::address_v4::loopback());
  impl->waker.open(address.is_v6() ? udp::v6() : udp::v4(), ec);
  if (!ec) impl->waker.bind(udp::endpoint(wake_to, 0), ec);
  if (!ec) impl->waker.connect(udp::endpoint(wake_to, port), ec);
  if (!ec) impl->waker_address = impl->waker.local_endpoint(ec);
  if (ec)
    return Error{ErrorCode::kIoError, "cannot open the endpoint's waker: " + ec.message(), "port"};
  impl->events.reserve(4096);  // state changes between two takes (the sampler's 33 ms)
  // The visual sender exists before the I/O threads start and outlives them (Stop): they read
  // the pointer on every new source address without a lock.
  if (options.visual_hz > 0) {
    auto visual = VisualSender::Create(address, options.visual_hz);
    if (visual.ok()) impl->visual = std::move(visual).value();  // else: forces only, no frames
  }
  for (auto& lane : impl->lanes) {
    Impl::Lane* l = lane.get();
    l->thread = std::thread([l] { l->Loop(); });
  }
  return std::unique_ptr<UdpEndpoint>(new UdpEndpoint(std::move(impl)));
}

UdpEndpoint::UdpEndpoint(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

UdpEndpoint::~UdpEndpoint() {
  Stop();
}

uint16_t UdpEndpoint::port() const {
  boost::system::error_code ec;
  return impl_->lanes[0]->socket.local_endpoint(ec).port();
}

int UdpEndpoint::io_threads() const {
  return static_cast<int>(impl_->lanes.size());
}

int UdpEndpoint::LaneOf(uint64_t id) const {
  return LaneOfId(id, io_threads());
}

void UdpEndpoint::AddSession(uint64_t id, const wire::SessionKey& key, sim::Simulation* simulation,
                             LinkStats* link) {
  Impl* p = impl_.get();
  Impl::Lane& lane = p->LaneOf(id);
  lane.Run([p, &lane, id, &key, simulation, link] {
    lane.sessions.insert_or_assign(
        id, Impl::Session(key, simulation, link, p->options.max_packets_per_s * 0.1, p->Now()));
    if (p->visual) p->visual->Add(id, key, simulation);
  });
}

void UdpEndpoint::AddChannel(uint64_t channel, ChannelRole role, const wire::SessionKey& key,
                             sim::Simulation* simulation, LinkStats* link) {
  Impl* p = impl_.get();
  Impl::Lane& lane = p->LaneOf(channel);
  lane.Run([p, &lane, channel, role, &key, simulation, link] {
    Impl::Session s(key, simulation, link, p->options.max_packets_per_s * 0.1, p->Now());
    s.role = role;
    lane.sessions.insert_or_assign(channel, std::move(s));
  });
}

void UdpEndpoint::RemoveSession(uint64_t id) {
  Impl* p = impl_.get();
  Impl::Lane& lane = p->LaneOf(id);
  lane.Run([p, &lane, id] {
    lane.sessions.erase(id);
    if (p->visual) p->visual->Remove(id);
  });
}

void UdpEndpoint::NoticeMoved(uint64_t id, const wire::SessionKey& key, double for_s) {
  Impl* p = impl_.get();
  Impl::Lane& lane = p->LaneOf(id);
  lane.Run([p, &lane, id, &key, for_s] {
    if (p->visual) p->visual->Remove(id);
    Impl::Session s(key, nullptr, nullptr, p->options.max_packets_per_s * 0.1, p->Now());
    s.moved_until = p->Now() + for_s;
    lane.sessions.insert_or_assign(id, std::move(s));
  });
}

void UdpEndpoint::Stop() {
  if (!impl_) return;
  impl_->stop.store(true, std::memory_order_release);
  for (auto& lane : impl_->lanes) {
    if (!lane->thread.joinable()) continue;
    impl_->Wake(lane->index);
    lane->thread.join();
    boost::system::error_code ec;
    lane->socket.close(ec);
  }
  impl_->visual.reset();  // after the I/O threads, the sender's readers, have ended
}

EndpointCounters UdpEndpoint::counters() const {
  EndpointCounters c;
  for (int i = 0; i < io_threads(); ++i) {
    const EndpointCounters l = counters(i);
    c.received += l.received;
    c.answered += l.answered;
    c.busy_polls += l.busy_polls;
    c.busy_polled += l.busy_polled;
    for (size_t r = 0; r < c.dropped.size(); ++r) c.dropped[r] += l.dropped[r];
    for (size_t b = 0; b < c.residence_buckets.size(); ++b)
      c.residence_buckets[b] += l.residence_buckets[b];
    c.residence_seconds += l.residence_seconds;
  }
  c.frames = impl_->visual ? impl_->visual->frames() : 0;
  c.frame_chunks = impl_->visual ? impl_->visual->chunks() : 0;
  c.frame_bytes = impl_->visual ? impl_->visual->bytes() : 0;
  return c;
}

EndpointCounters UdpEndpoint::counters(int lane) const {
  const Impl::Lane& l = *impl_->lanes.at(static_cast<size_t>(lane));
  EndpointCounters c;
  c.received = l.received.load();
  c.answered = l.answered.load();
  c.busy_polls = l.busy_polls.load();
  c.busy_polled = l.busy_polled.load();
  for (size_t i = 0; i < c.dropped.size(); ++i) c.dropped[i] = l.dropped[i].load();
  for (size_t b = 0; b < c.residence_buckets.size(); ++b)
    c.residence_buckets[b] = l.residence[b].load();
  c.residence_seconds = 1e-9 * static_cast<double>(l.residence_ns.load());
  return c;
}

double EndpointCounters::ResidenceQuantile(double q) const {
  uint64_t total = 0;
  for (uint64_t n : residence_buckets) total += n;
  if (total == 0) return 0;
  const double want = q * static_cast<double>(total);
  uint64_t below = 0;
  for (size_t b = 0; b < kResidenceBounds.size(); ++b) {
    below += residence_buckets[b];
    if (static_cast<double>(below) >= want) return kResidenceBounds[b];
  }
  return std::numeric_limits<double>::infinity();
}

int UdpEndpoint::receive_buffer_bytes() const {
  int bytes = 0;
  socklen_t size = sizeof bytes;
  if (::getsockopt(impl_->lanes[0]->socket.native_handle(), SOL_SOCKET, SO_RCVBUF, &bytes, &size) !=
      0)
    return 0;
  return bytes;
}

double UdpEndpoint::io_cpu_seconds() const {
  double sum = 0;
  for (const auto& lane : impl_->lanes) sum += lane->io_cpu.load();
  return sum;
}

void UdpEndpoint::CheckTimeoutsNow() {
  for (auto& lane : impl_->lanes) {
    Impl::Lane* l = lane.get();
    l->Run([l] { l->CheckTimeouts(); });
  }
}

void UdpEndpoint::RunOnIoThread(std::function<void()> fn, int lane) {
  impl_->lanes.at(static_cast<size_t>(lane))->Run(std::move(fn));
}

std::thread::id UdpEndpoint::io_thread_id(int lane) const {
  return impl_->lanes.at(static_cast<size_t>(lane))->thread.get_id();
}

std::vector<SessionEvent> UdpEndpoint::TakeEvents() {
  // Copied out and cleared, not swapped: the I/O threads' vector keeps its capacity, so recording
  // a stall or a resumption there never allocates (the copy allocates on the caller's thread).
  std::lock_guard<std::mutex> lock(impl_->events_mutex);
  std::vector<SessionEvent> out(impl_->events.begin(), impl_->events.end());
  impl_->events.clear();
  return out;
}

}  // namespace vsurg::server
