// The user-space impairment relay: a UDP forwarder between stations and a server that delays,
// jitters, reorders, loses, duplicates and cuts datagrams by a Profile (bench/relay/impairment.h),
// per direction, from a seed. This kernel has no `netem` qdisc, so this is how vsurg measures
// haptics across a real network's habits (docs/BENCHMARKS.md "Haptics across networks").
//
// Like a NAT, each station (source address) gets its own socket toward the server, so several
// stations share one relay and the server sees each at its own address. A server started with
// `--public-host`/`--public-port` naming the relay sends its stations through it.
//
// One thread: ppoll on the sockets with the next departure's time as its timeout, departures
// kept in a heap by release time. Times are the relay's own (steady clock, s since the first
// datagram), so outages are placed relative to the start of traffic.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "bench/relay/impairment.h"
#include "common/core/expected.h"

namespace vsurg::relay {

struct RelayOptions {
  std::string listen_host = "127.0.0.1";
  uint16_t listen_port = 0;  // 0: any free port
  std::string server_host = "127.0.0.1";
  uint16_t server_port = 0;
  Profile profile;
  uint64_t seed = 1;
  int max_flows = 256;  // stations (source addresses) the relay keeps a socket for
};

struct DirectionStats {
  uint64_t received = 0, forwarded = 0, duplicated = 0;
  uint64_t lost_random = 0, lost_burst = 0, lost_outage = 0;
  uint64_t reordered = 0;  // left after a datagram that arrived later
  double mean_delay_ms = 0;
};

struct RelayStats {
  DirectionStats up, down;  // station → server, server → station
  uint64_t flows = 0, refused_flows = 0;
};

class Relay {
 public:
  static Expected<std::unique_ptr<Relay>> Start(const RelayOptions& options);
  ~Relay();  // stops and joins
  void Stop();

  uint16_t port() const;     // the stations' side
  RelayStats stats() const;  // any thread
  // Any thread: drop every datagram both ways while on (a cable pulled), on top of the profile.
  void SetBlackhole(bool on);

 private:
  struct Impl;
  explicit Relay(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::relay
