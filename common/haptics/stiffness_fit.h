// The stiffness a contact shows the hand, fitted to what the server computed ("a
// local model that is the tissue's").
//
// The station extrapolates its force between two answers with the local model's Jacobian,
// F(x) = F₀ + J·(x − x₀), J = −k·n·nᵀ. The proxy's spring k_p is the right k only on a surface
// that does not yield. Deformable tissue gives way under the proxy, so the hand feels the proxy
// in series with the tissue, k = (1/k_p + 1/k_t)⁻¹ < k_p. Extrapolating with k_p over a round
// trip of motion then overshoots when pressing in and undershoots when letting up. On the
// sphere at 700 N/m the hand felt 82% of the reference's stiffness at 110 ms, with a 12% force
// error (docs/BENCHMARKS.md). Rather than the tissue's point compliance (a solve per surface
// vertex, and only the static part of it), the slope is fitted to the samples themselves: the force
// along the contact's rest normal, f, over the tool's depth along it, d, by exponentially
// weighted least squares with time constant τ:
//
//   S₀ = Σ wᵢ, S_d = Σ wᵢdᵢ, S_f = Σ wᵢfᵢ, S_dd = Σ wᵢdᵢ², S_df = Σ wᵢdᵢfᵢ,  wᵢ = e^(−(t − tᵢ)/τ)
//   k = cov(d, f) / var(d) = (S₀S_df − S_dS_f) / (S₀S_dd − S_d²)
//
// A fit is used only while the depths spread over at least `min_spread_m` (their weighted
// standard deviation): a resting or trembling tool says nothing about the slope. Until then the
// last fitted slope stands (the same tissue), and before any fit the caller's prior (k_p). The
// result is clamped to the caller's bounds. Depths are taken from the contact's start, so the
// sums stay small and well conditioned. Units: m, N, s, N/m. Plain data, no allocation.
#pragma once

#include <algorithm>
#include <cmath>

namespace vsurg::haptics {

class StiffnessFit {
 public:
  static constexpr double kTimeConstantS = 0.15;
  static constexpr double kMinSpreadM = 0.3e-3;

  // A new contact: its samples start afresh; the last fitted slope is kept.
  void BeginContact() { s0_ = sd_ = sf_ = sdd_ = sdf_ = 0; }

  // One sample in contact, `dt_s` after the previous one; one with a non-finite value is ignored.
  void Add(double depth_m, double force_n, double dt_s) {
    if (!std::isfinite(depth_m) || !std::isfinite(force_n) || !std::isfinite(dt_s)) return;
    const double keep = std::exp(-std::clamp(dt_s, 0.0, 1.0) / kTimeConstantS);
    s0_ = keep * s0_ + 1;
    sd_ = keep * sd_ + depth_m;
    sf_ = keep * sf_ + force_n;
    sdd_ = keep * sdd_ + depth_m * depth_m;
    sdf_ = keep * sdf_ + depth_m * force_n;
    const double var = s0_ * sdd_ - sd_ * sd_;  // S₀²·var(d)
    if (var > s0_ * s0_ * kMinSpreadM * kMinSpreadM) {
      const double k = (s0_ * sdf_ - sd_ * sf_) / var;
      if (std::isfinite(k) && k > 0) last_ = k;  // a falling slope (a transient) says nothing
    }
  }

  // The slope to render with: the last fit within [lo, hi]; `prior` before any fit.
  double Stiffness(double lo, double hi, double prior) const {
    return last_ > 0 ? std::clamp(last_, lo, hi) : prior;
  }

  template <class A>
  void Persist(A& a) {
    a(s0_, sd_, sf_, sdd_, sdf_, last_);
  }

 private:
  double s0_ = 0, sd_ = 0, sf_ = 0, sdd_ = 0, sdf_ = 0;
  double last_ = 0;
};

}  // namespace vsurg::haptics
