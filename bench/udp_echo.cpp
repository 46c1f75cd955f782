#include "bench/udp_echo.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <unistd.h>

#include <array>
#include <chrono>
#include <cstring>
#include <ctime>

#include "common/core/realtime.h"

namespace vsurg::bench {

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

Expected<std::unique_ptr<UdpEcho>> UdpEcho::Start(const Options& options) {
  if (options.batch < 1 || options.batch > kMaxBatch)
    return InvalidArgument("batch", "must be within [1, 64]");
  auto e = std::unique_ptr<UdpEcho>(new UdpEcho);
  e->fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (e->fd_ < 0) return Error{ErrorCode::kIoError, "socket() failed", "socket"};
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  timeval timeout{0, 50000};  // wakes to see a stop request
  if (::bind(e->fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(e->fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0 ||
      ::setsockopt(e->fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout) != 0)
    return Error{ErrorCode::kIoError, "cannot bind the echo socket", "socket"};
  e->port_ = ntohs(a.sin_port);
  e->thread_ = std::thread([p = e.get(), options] {
    if (options.priority > 0) TrySetRealtimePriority(options.priority);
    if (options.batch > 1)
      p->Batched(options.batch);
    else
      p->Plain(options);
    p->cpu_s_ = ThreadCpuSeconds();
  });
  return e;
}

// One datagram a call each way. With busy_poll_us > 0, before it blocks it polls for up to that
// long while the last 50 ms brought at least one datagram per window.
void UdpEcho::Plain(const Options& options) {
  std::array<uint8_t, 2048> buf{};
  using Steady = std::chrono::steady_clock;
  const std::chrono::microseconds window(options.busy_poll_us);
  const std::chrono::milliseconds tick(50);
  bool poll = false;
  uint64_t count_at_tick = 0;
  Steady::time_point next_tick = Steady::now() + tick;
  while (!stop_.load(std::memory_order_relaxed)) {
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    ssize_t got = -1;
    if (poll) {
      const Steady::time_point until = Steady::now() + window;
      do {
        from_len = sizeof from;
        got = ::recvfrom(fd_, buf.data(), buf.size(), MSG_DONTWAIT,
                         reinterpret_cast<sockaddr*>(&from), &from_len);
      } while (got <= 0 && Steady::now() < until);
    }
    if (got <= 0) {
      from_len = sizeof from;
      got =
          ::recvfrom(fd_, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &from_len);
    }
    if (got > 0) {
      ++answered_, ++calls_;
      ::sendto(fd_, buf.data(), static_cast<size_t>(got), 0, reinterpret_cast<sockaddr*>(&from),
               from_len);
    }
    if (options.busy_poll_us > 0 && Steady::now() >= next_tick) {
      const double elapsed =
          std::chrono::duration<double>(Steady::now() - (next_tick - tick)).count();
      poll =
          static_cast<double>(answered_ - count_at_tick) * options.busy_poll_us * 1e-6 >= elapsed;
      count_at_tick = answered_;
      next_tick = Steady::now() + tick;
    }
  }
}

// Blocks for the first datagram, takes what else is queued (up to `batch`) in the same call and
// answers every one in one sendmmsg, each to its sender.
void UdpEcho::Batched(int batch) {
  const int on = 1;
  const bool stamped = ::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) == 0;
  residences_us_.reserve(kMaxResidences);
  constexpr size_t kControl = CMSG_SPACE(sizeof(timespec));
  std::array<std::array<uint8_t, kControl>, kMaxBatch> control{};
  std::array<std::array<uint8_t, 2048>, kMaxBatch> bufs{};
  std::array<sockaddr_in, kMaxBatch> from{};
  std::array<iovec, kMaxBatch> rx_iov{}, tx_iov{};
  std::array<mmsghdr, kMaxBatch> rx{}, tx{};
  for (int i = 0; i < batch; ++i) {
    rx_iov[i] = {bufs[i].data(), bufs[i].size()};
    rx[i].msg_hdr.msg_iov = &rx_iov[i];
    rx[i].msg_hdr.msg_iovlen = 1;
    rx[i].msg_hdr.msg_name = &from[i];
    tx[i].msg_hdr.msg_iov = &tx_iov[i];
    tx[i].msg_hdr.msg_iovlen = 1;
    tx[i].msg_hdr.msg_name = &from[i];
  }
  while (!stop_.load(std::memory_order_relaxed)) {
    for (int i = 0; i < batch; ++i) {
      rx[i].msg_hdr.msg_namelen = sizeof(sockaddr_in);
      rx[i].msg_hdr.msg_control = control[i].data();
      rx[i].msg_hdr.msg_controllen = kControl;
    }
    const int n = ::recvmmsg(fd_, rx.data(), static_cast<unsigned>(batch), MSG_WAITFORONE, nullptr);
    if (n <= 0) continue;  // the timeout: look at the stop flag
    for (int i = 0; i < n; ++i) {
      tx_iov[i] = {bufs[i].data(), rx[i].msg_len};
      tx[i].msg_hdr.msg_namelen = rx[i].msg_hdr.msg_namelen;
    }
    for (int sent = 0; sent < n;) {
      const int k = ::sendmmsg(fd_, tx.data() + sent, static_cast<unsigned>(n - sent), 0);
      if (k <= 0) break;  // a full send buffer: the rest are lost, as any UDP answer may be
      sent += k;
    }
    if (stamped) Residences(rx.data(), n);
    answered_ += static_cast<uint64_t>(n);
    ++calls_;
  }
}

// Each datagram's time from its kernel arrival stamp to now (its answer just sent).
void UdpEcho::Residences(mmsghdr* rx, int n) {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  for (int i = 0; i < n && residences_us_.size() < kMaxResidences; ++i) {
    for (cmsghdr* c = CMSG_FIRSTHDR(&rx[i].msg_hdr); c != nullptr;
         c = CMSG_NXTHDR(&rx[i].msg_hdr, c)) {
      if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS) continue;
      timespec at{};
      std::memcpy(&at, CMSG_DATA(c), sizeof at);
      residences_us_.push_back(1e6 * static_cast<double>(now.tv_sec - at.tv_sec) +
                               1e-3 * static_cast<double>(now.tv_nsec - at.tv_nsec));
    }
  }
}

UdpEcho::~UdpEcho() {
  Stop();
  if (fd_ >= 0) ::close(fd_);
}

void UdpEcho::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

}  // namespace vsurg::bench
