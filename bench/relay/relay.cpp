#include "bench/relay/relay.h"

#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <map>
#include <mutex>
#include <queue>
#include <thread>
#include <vector>

namespace vsurg::relay {

namespace {

constexpr size_t kMaxDatagram = 65536;

struct Address {
  sockaddr_storage storage{};
  socklen_t length = 0;
  bool operator<(const Address& o) const {
    if (length != o.length) return length < o.length;
    return std::memcmp(&storage, &o.storage, length) < 0;
  }
};

Expected<Address> Resolve(const std::string& host, uint16_t port, const std::string& field) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  hints.ai_flags = AI_NUMERICHOST | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0 || !found)
    return InvalidArgument(field, "'" + host + "' is not an IP address");
  Address a;
  std::memcpy(&a.storage, found->ai_addr, found->ai_addrlen);
  a.length = found->ai_addrlen;
  freeaddrinfo(found);
  return a;
}

uint16_t PortOf(int fd) {
  sockaddr_storage s{};
  socklen_t n = sizeof s;
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&s), &n) != 0) return 0;
  if (s.ss_family == AF_INET) return ntohs(reinterpret_cast<sockaddr_in*>(&s)->sin_port);
  return ntohs(reinterpret_cast<sockaddr_in6*>(&s)->sin6_port);
}

}  // namespace

struct Relay::Impl {
  struct Flow {
    Address station;
    int fd = -1;  // toward the server
    Impairment up, down;
    uint64_t up_arrivals = 0, down_arrivals = 0;
    uint64_t up_latest_departed = 0, down_latest_departed = 0;
  };
  struct Departure {
    double release_s;
    uint64_t order;    // FIFO among equal release times
    uint64_t arrival;  // the datagram's arrival index in its direction of its flow
    int flow;
    bool up;
    std::vector<uint8_t> bytes;
    bool operator>(const Departure& o) const {
      return release_s != o.release_s ? release_s > o.release_s : order > o.order;
    }
  };

  RelayOptions options;
  Address server;
  int front = -1, wake = -1;
  std::vector<Flow> flows;
  std::map<Address, int> flow_of;
  std::priority_queue<Departure, std::vector<Departure>, std::greater<>> heap;
  uint64_t order = 0;
  std::chrono::steady_clock::time_point t0;
  bool started = false;
  std::thread thread;
  std::atomic<bool> stop{false}, blackhole{false};
  mutable std::mutex stats_mutex;
  RelayStats stats;
  double up_delay_sum = 0, down_delay_sum = 0;
  std::vector<uint8_t> rx = std::vector<uint8_t>(kMaxDatagram);

  double Now() {
    if (!started) t0 = std::chrono::steady_clock::now(), started = true;
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  ~Impl() {
    for (Flow& f : flows) close(f.fd);
    if (front >= 0) close(front);
    if (wake >= 0) close(wake);
  }

  int FlowFor(const Address& station) {
    if (auto it = flow_of.find(station); it != flow_of.end()) return it->second;
    if (static_cast<int>(flows.size()) >= options.max_flows) return -1;
    const int fd = socket(server.storage.ss_family, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    if (connect(fd, reinterpret_cast<const sockaddr*>(&server.storage), server.length) != 0) {
      close(fd);
      return -1;
    }
    // Each flow's two directions draw from their own streams: a station's fates do not depend
    // on how many others share the relay or in which order they began.
    const uint64_t k = flows.size();
    flows.push_back(Flow{station, fd,
                         Impairment(options.profile.up, options.seed * 1000003 + 2 * k),
                         Impairment(options.profile.down, options.seed * 1000003 + 2 * k + 1)});
    flow_of[station] = static_cast<int>(k);
    std::lock_guard<std::mutex> lock(stats_mutex);
    stats.flows = flows.size();
    return static_cast<int>(k);
  }

  void Admit(int flow, bool up, size_t n, double now) {
    Flow& f = flows[flow];
    DirectionStats& s = up ? stats.up : stats.down;
    const uint64_t arrival = up ? ++f.up_arrivals : ++f.down_arrivals;
    std::lock_guard<std::mutex> lock(stats_mutex);
    ++s.received;
    if (blackhole.load(std::memory_order_relaxed)) {
      ++s.lost_outage;
      return;
    }
    const Fate fate = (up ? f.up : f.down).Decide(now);
    if (fate.lost) {
      switch (fate.why) {
        case Fate::Why::kOutage:
          ++s.lost_outage;
          break;
        case Fate::Why::kBurst:
          ++s.lost_burst;
          break;
        default:
          ++s.lost_random;
          break;
      }
      return;
    }
    (up ? up_delay_sum : down_delay_sum) += (fate.release_s - now) * 1e3;
    std::vector<uint8_t> bytes(rx.begin(), rx.begin() + static_cast<std::ptrdiff_t>(n));
    if (fate.copy_release_s) {
      ++s.duplicated;
      heap.push(Departure{*fate.copy_release_s, order++, arrival, flow, up, bytes});
    }
    heap.push(Departure{fate.release_s, order++, arrival, flow, up, std::move(bytes)});
  }

  void Depart(double now) {
    while (!heap.empty() && heap.top().release_s <= now) {
      const Departure& d = heap.top();
      Flow& f = flows[d.flow];
      if (d.up) {
        (void)send(f.fd, d.bytes.data(), d.bytes.size(), MSG_DONTWAIT);
      } else {
        (void)sendto(front, d.bytes.data(), d.bytes.size(), MSG_DONTWAIT,
                     reinterpret_cast<const sockaddr*>(&f.station.storage), f.station.length);
      }
      uint64_t& latest = d.up ? f.up_latest_departed : f.down_latest_departed;
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        DirectionStats& s = d.up ? stats.up : stats.down;
        ++s.forwarded;
        if (d.arrival < latest) ++s.reordered;
      }
      latest = std::max(latest, d.arrival);
      heap.pop();
    }
  }

  void Loop() {
    std::vector<pollfd> fds;
    while (!stop.load()) {
      fds.clear();
      fds.push_back({wake, POLLIN, 0});
      fds.push_back({front, POLLIN, 0});
      for (const Flow& f : flows) fds.push_back({f.fd, POLLIN, 0});
      timespec timeout{1, 0};
      if (!heap.empty()) {
        const double wait = std::max(0.0, heap.top().release_s - Now());
        timeout.tv_sec = static_cast<time_t>(wait);
        timeout.tv_nsec = static_cast<long>((wait - static_cast<double>(timeout.tv_sec)) * 1e9);
      }
      const int ready = ppoll(fds.data(), fds.size(), &timeout, nullptr);
      if (ready < 0 && errno != EINTR) break;
      const double now = Now();
      if (ready > 0) {
        if (fds[1].revents & POLLIN) {
          for (;;) {  // drain the stations' side
            Address from;
            from.length = sizeof from.storage;
            const ssize_t n = recvfrom(front, rx.data(), rx.size(), MSG_DONTWAIT,
                                       reinterpret_cast<sockaddr*>(&from.storage), &from.length);
            if (n < 0) break;
            const int flow = FlowFor(from);
            if (flow < 0) {
              std::lock_guard<std::mutex> lock(stats_mutex);
              ++stats.refused_flows;
              continue;
            }
            Admit(flow, true, static_cast<size_t>(n), now);
          }
        }
        for (size_t i = 2; i < fds.size(); ++i) {
          if (!(fds[i].revents & POLLIN)) continue;
          const int flow = static_cast<int>(i - 2);
          for (;;) {
            const ssize_t n = recv(flows[flow].fd, rx.data(), rx.size(), MSG_DONTWAIT);
            if (n < 0) break;
            Admit(flow, false, static_cast<size_t>(n), now);
          }
        }
      }
      Depart(Now());
    }
  }
};

Expected<std::unique_ptr<Relay>> Relay::Start(const RelayOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  auto server = Resolve(options.server_host, options.server_port, "server");
  if (!server.ok()) return server.error();
  if (options.server_port == 0) return InvalidArgument("server", "the server's port is required");
  impl->server = *server;
  auto listen = Resolve(options.listen_host, options.listen_port, "listen");
  if (!listen.ok()) return listen.error();
  impl->front = socket(listen->storage.ss_family, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (impl->front < 0 ||
      bind(impl->front, reinterpret_cast<const sockaddr*>(&listen->storage), listen->length) != 0)
    return Error{ErrorCode::kIoError,
                 "cannot bind " + options.listen_host + ":" + std::to_string(options.listen_port) +
                     ": " + std::strerror(errno),
                 "listen"};
  // Room for a few hundred milliseconds of 1 kHz traffic from many stations.
  const int buffer = 4 << 20;
  setsockopt(impl->front, SOL_SOCKET, SO_RCVBUF, &buffer, sizeof buffer);
  impl->wake = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (impl->wake < 0) return Error{ErrorCode::kIoError, "eventfd failed", "relay"};
  Impl* p = impl.get();
  impl->thread = std::thread([p] { p->Loop(); });
  return std::unique_ptr<Relay>(new Relay(std::move(impl)));
}

Relay::Relay(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Relay::~Relay() {
  Stop();
}

void Relay::Stop() {
  if (!impl_ || impl_->stop.exchange(true)) return;
  const uint64_t one = 1;
  (void)write(impl_->wake, &one, sizeof one);
  if (impl_->thread.joinable()) impl_->thread.join();
}

uint16_t Relay::port() const {
  return PortOf(impl_->front);
}

RelayStats Relay::stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  RelayStats s = impl_->stats;
  const auto mean = [](double sum, uint64_t n) { return n ? sum / static_cast<double>(n) : 0.0; };
  const uint64_t up_kept = s.up.received - s.up.lost_random - s.up.lost_burst - s.up.lost_outage;
  const uint64_t down_kept =
      s.down.received - s.down.lost_random - s.down.lost_burst - s.down.lost_outage;
  s.up.mean_delay_ms = mean(impl_->up_delay_sum, up_kept);
  s.down.mean_delay_ms = mean(impl_->down_delay_sum, down_kept);
  return s;
}

void Relay::SetBlackhole(bool on) {
  impl_->blackhole = on;
}

}  // namespace vsurg::relay
