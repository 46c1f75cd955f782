#include "bench/relay/impairment.h"

#include <algorithm>
#include <cmath>

namespace vsurg::relay {

double DirectionParams::MeanLoss() const {
  const double sum = p_good_to_bad + p_bad_to_good;
  const double pi_bad = sum > 0 ? p_good_to_bad / sum : 0.0;
  return (1 - pi_bad) * loss_good + pi_bad * loss_bad;
}

void BurstLoss(DirectionParams& d, double rate, double burst) {
  rate = std::clamp(rate, 0.0, 0.99);
  burst = std::max(1.0, burst);
  if (burst <= 1.0) {  // independent losses
    d.p_good_to_bad = 0, d.p_bad_to_good = 1, d.loss_good = rate, d.loss_bad = 1;
    return;
  }
  d.p_bad_to_good = 1.0 / burst;
  d.p_good_to_bad = d.p_bad_to_good * rate / (1.0 - rate);
  d.loss_good = 0, d.loss_bad = 1;
}

namespace {

Profile Make(std::string name, std::string summary, double base_ms, double jitter_ms, double loss,
             double burst, bool reorder = false) {
  Profile p;
  p.name = std::move(name);
  p.summary = std::move(summary);
  p.up.base_ms = base_ms;
  p.up.jitter_ms = jitter_ms;
  p.up.reorder = reorder;
  BurstLoss(p.up, loss, burst);
  p.down = p.up;
  return p;
}

}  // namespace

const std::vector<Profile>& Profiles() {
  static const std::vector<Profile> profiles = [] {
    std::vector<Profile> v;
    v.push_back(Make("none", "no impairment (the reference through the same relay)", 0, 0, 0, 1));
    v.push_back(Make("lan", "0.25 ms each way", 0.25, 0, 0, 1));
    v.push_back(Make("metro", "10 ± 1 ms", 10, 1, 0, 1));
    v.push_back(Make("regional", "25 ± 3 ms, 0.5% loss", 25, 3, 0.005, 1));
    v.push_back(Make("continental", "50 ± 5 ms, 2% loss in 4 ms bursts", 50, 5, 0.02, 4));
    v.push_back(Make("intercontinental", "150 ± 10 ms, 1% loss", 150, 10, 0.01, 1));
    // Wi-Fi: retransmissions at the link layer reorder, interference comes in bursts, and a
    // roam between access points is an outage.
    Profile wifi =
        Make("bad-wifi",
             "3 ± 8 ms reordering, 5% loss in 8 ms bursts, 1% duplicates, a 500 ms outage at 4 s",
             3, 8, 0.05, 8, true);
    wifi.up.duplicate = wifi.down.duplicate = 0.01;
    wifi.up.outage_at_s = wifi.down.outage_at_s = 4.0;
    wifi.up.outage_s = wifi.down.outage_s = 0.5;
    v.push_back(wifi);
    return v;
  }();
  return profiles;
}

Expected<Profile> ProfileByName(const std::string& name) {
  std::string known;
  for (const Profile& p : Profiles()) {
    if (p.name == name) return p;
    known += (known.empty() ? "" : ", ") + p.name;
  }
  return InvalidArgument("profile", "unknown profile '" + name + "' (known: " + known + ")");
}

Impairment::Impairment(const DirectionParams& params, uint64_t seed)
    : params_(params), rng_(seed) {}

Fate Impairment::Decide(double arrival_s) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> n(0.0, 1.0);
  // Draw every random number on every call, whatever the outcome, so that one parameter's
  // change does not shift the others' sequences (two profiles differ only where they differ).
  const double u_state = u(rng_), u_loss = u(rng_), u_dup = u(rng_);
  const double z = std::clamp(n(rng_), -2.0, 2.0);
  // Advance the chain by the milliseconds since the previous datagram (at least one step).
  const double steps =
      last_arrival_s_ < 0 ? 1.0 : std::max(1.0, std::round((arrival_s - last_arrival_s_) * 1e3));
  last_arrival_s_ = arrival_s;
  const double p = params_.p_good_to_bad, r = params_.p_bad_to_good;
  if (steps <= 1.0 || p + r <= 0) {
    bad_ = bad_ ? !(u_state < r) : (u_state < p);
  } else {
    const double pi_bad = p / (p + r);
    const double p_bad = pi_bad + ((bad_ ? 1.0 : 0.0) - pi_bad) * std::pow(1.0 - p - r, steps);
    bad_ = u_state < p_bad;
  }
  Fate f;
  if (params_.outage_at_s >= 0 && arrival_s >= params_.outage_at_s &&
      arrival_s < params_.outage_at_s + params_.outage_s) {
    f.lost = true, f.why = Fate::Why::kOutage;
    return f;
  }
  if (u_loss < (bad_ ? params_.loss_bad : params_.loss_good)) {
    f.lost = true;
    f.why = bad_ && params_.p_good_to_bad > 0 ? Fate::Why::kBurst : Fate::Why::kRandom;
    return f;
  }
  const double delay_s = std::max(0.0, params_.base_ms + params_.jitter_ms * z) * 1e-3;
  f.release_s = arrival_s + delay_s;
  if (!params_.reorder) f.release_s = std::max(f.release_s, last_release_s_);
  last_release_s_ = std::max(last_release_s_, f.release_s);
  if (u_dup < params_.duplicate) f.copy_release_s = f.release_s + params_.dup_gap_ms * 1e-3;
  return f;
}

}  // namespace vsurg::relay
