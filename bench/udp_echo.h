// The floor a UDP round trip allows on this machine, for vsurg-bench udp-floor: an echo on
// loopback answering each datagram with itself (no authentication, no decoding, no physics, no
// event loop). POSIX calls, not Asio: the floor should carry nothing of ours.
#pragma once

#include <sys/socket.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "common/core/expected.h"

namespace vsurg::bench {

// The calling thread's CPU time so far, s.
double ThreadCpuSeconds();

class UdpEcho {
 public:
  struct Options {
    int priority = 0;      // SCHED_FIFO priority of the echo thread, when permitted (0: none)
    int busy_poll_us = 0;  // > 0: poll this long before blocking, by vsurg-server's rule
    // > 1: the batched echo. It blocks for the first datagram, takes up to `batch` queued ones
    // in one recvmmsg and answers them all in one sendmmsg, as the server's I/O thread does;
    // 1: one recvfrom and one sendto per datagram (the plain blocking echo).
    int batch = 1;
  };
  static constexpr int kMaxBatch = 64;

  static Expected<std::unique_ptr<UdpEcho>> Start(const Options& options);
  ~UdpEcho();
  void Stop();
  uint16_t port() const { return port_; }
  double cpu_seconds() const { return cpu_s_; }  // the echo thread's, after Stop
  uint64_t answered() const { return answered_; }
  uint64_t calls() const { return calls_; }  // receive calls that brought datagrams
  // The batched echo's residence per datagram, µs: from the kernel's arrival stamp
  // (SO_TIMESTAMPNS) to the return of the sendmmsg that answered it, as the endpoint's
  // vsurg_udp_residence_seconds; the first kMaxResidences, after Stop. Empty for the plain echo.
  const std::vector<double>& residences_us() const { return residences_us_; }
  static constexpr size_t kMaxResidences = 4'000'000;

 private:
  UdpEcho() = default;
  void Plain(const Options& options);
  void Batched(int batch);
  void Residences(mmsghdr* rx, int n);

  int fd_ = -1;
  uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  double cpu_s_ = 0;
  uint64_t answered_ = 0, calls_ = 0;
  std::vector<double> residences_us_;
  std::thread thread_;
};

}  // namespace vsurg::bench
