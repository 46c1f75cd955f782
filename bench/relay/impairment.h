// A network's habits, one direction at a time, for the user-space impairment relay
// (bench/relay/relay.h). The machines it runs on have no kernel `netem` qdisc to impair a link, so
// delay, jitter, loss, duplication, reordering and outages are decided here, in user space, from a
// seeded generator: the same seed and the same datagram times give the same fates, so a run
// repeats exactly.
//
// Model, per datagram arriving at time t (s, the relay's clock):
//   - outage: every datagram in [outage_at_s, outage_at_s + outage_s) is lost;
//   - loss: Gilbert–Elliott (Gilbert 1960, Elliott 1963), a two-state Markov chain that steps
//     once per millisecond of the link's time (a flow at 1 kHz: once per datagram): good → bad
//     with probability p, bad → good with r; a datagram is lost with probability loss_good in
//     the good state and loss_bad in the bad one. Between two datagrams n ms apart the chain is
//     advanced n steps at once, P(bad) = π + (s − π)·(1 − p − r)ⁿ (π = p/(p + r), s the state
//     before), so a burst lasts as long in time for a sparse flow (a station behind the
//     deadband) as for a full-rate one, rather than spanning as many of its sparse datagrams.
//     Random (Bernoulli) loss is p = 0 with loss_good = the rate. From a mean rate L and a mean
//     burst length B (ms): r = 1/B, p = r·L/(1 − L), loss_bad = 1, loss_good = 0 (BurstLoss());
//   - delay: base_ms + jitter, the jitter normal with σ = jitter_ms truncated at ±2σ, never
//     below zero in total; without reordering a datagram never leaves before the one sent
//     before it (a FIFO queue: jitter stretches gaps but keeps the order), with reordering each
//     datagram keeps its own delay and may overtake;
//   - duplication: with probability duplicate a second copy leaves dup_gap_ms after the first.
//
// Threads: one Impairment per direction, used by one thread. Units: s and ms as named.
#pragma once

#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/core/expected.h"

namespace vsurg::relay {

struct DirectionParams {
  double base_ms = 0;    // one-way delay
  double jitter_ms = 0;  // σ of the delay's variation
  bool reorder = false;  // jitter may reorder datagrams (false: FIFO)
  double p_good_to_bad = 0, p_bad_to_good = 1;
  double loss_good = 0, loss_bad = 1;
  double duplicate = 0;      // probability
  double dup_gap_ms = 0.05;  // the copy's lag behind the original
  double outage_at_s = -1;   // < 0: no outage
  double outage_s = 0;

  double MeanLoss() const;  // the chain's stationary loss rate
};

// Gilbert–Elliott parameters for a mean loss rate `rate` (0..1) in bursts of mean length
// `burst` datagrams (≥ 1; 1 means independent losses).
void BurstLoss(DirectionParams& d, double rate, double burst);

struct Profile {
  std::string name;
  std::string summary;   // one line: "25 ± 3 ms, 0.5% loss"
  DirectionParams up;    // station → server
  DirectionParams down;  // server → station
};

// The named profiles: lan, metro, regional, continental, intercontinental, bad-wifi, and
// `none` (no impairment at all: the reference run goes through the same relay).
const std::vector<Profile>& Profiles();
Expected<Profile> ProfileByName(const std::string& name);

// What happens to one datagram.
struct Fate {
  bool lost = false;
  enum class Why { kNone, kRandom, kBurst, kOutage } why = Why::kNone;
  double release_s = 0;                  // when it leaves the relay
  std::optional<double> copy_release_s;  // a duplicate's departure
};

class Impairment {
 public:
  Impairment(const DirectionParams& params, uint64_t seed);
  // A datagram arriving at `arrival_s` (non-decreasing across calls).
  Fate Decide(double arrival_s);

 private:
  DirectionParams params_;
  std::mt19937_64 rng_;
  bool bad_ = false;
  double last_arrival_s_ = -1;
  double last_release_s_ = 0;
};

}  // namespace vsurg::relay
