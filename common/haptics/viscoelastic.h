// A contact's local model with the tissue's own stiffness and damping ("a local
// model that is the tissue's"), fitted at the server and integrated at the station.
//
// Under the proxy the tissue's surface yields, and it yields viscously: pressed from 3 to 4 mm
// the stiff sphere's force rose at ~150 N/m, and on a reversal it first fell ~0.2 N within
// 0.5 mm (docs/BENCHMARKS.md). No single slope extrapolates both: the proxy's spring k_p
// overshoots a press by a round trip's motion (12% error at 110 ms), and the loading slope
// keeps pushing after the reference has let go. The contact is a standard linear solid: the
// proxy's spring k_p in series with the tissue point, a Kelvin–Voigt element,
//
//   f = k_p·(d − S)              the force along the contact's rest normal (N); d the tool's
//                                depth, S the surface's yield under the proxy (m)
//   b·Ṡ = f − (a + k_t·S)        the tissue: elastic a + k_t·S about the operating point, viscous
//   b·Ṡ
//
// which holds the sphere's force over any horizon the grid uses: replaying the scripted press
// open loop, the model predicts the server's force 20–330 ms ahead within 0.7–0.9% of the peak,
// against 5–37% for k_p and 2–7% for the best single slope.
//
// ViscoelasticFit (server): a, k_t and b by exponentially weighted least squares over the
// samples in contact. The ODE integrated over a window [t_j, t_i] of at least kWindowS, each
// integral by the trapezoid, is exactly linear in the unknowns:
//
//   f̄ = a + k_t·S̄ + b·(S_i − S_j)/(t_i − t_j),   f̄, S̄ the window's endpoint means,
//
// so the fit needs no derivative of a noisy signal and works at the deadband's 50 samples/s as at
// 1 kHz. A fit is used only while S and Ṡ both spread (a tool at rest says nothing about b); until
// then the last fit stands, before any none (the station renders the proxy's spring).
//
// ViscoelasticContact (station): S's change σ since an answered sample, integrated by implicit
// Euler (stable at any step) over the station's own depths from the sample's time on, so the
// station's force is the tissue's however late the answer came:
//
//   f(σ, u) = f₀ + k_p·(u − σ),   b·σ̇ = f − e₀ − k_t·σ,   u = n·(x₀ − x)
//
// with f₀ the answer's force along n and e₀ = a + k_t·S₀ the tissue's elastic force then. Where
// f ≤ 0 the tool has left the surface: no force, and the surface recovers on its own (b·σ̇ =
// −e₀ − k_t·σ). A spring–dashpot network with k_p, k_t, b ≥ 0 is passive.
//
// Units: m, s, N, N/m, N·s/m. Plain data, no allocation; any thread that owns the object.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace vsurg::haptics {

struct ViscoelasticParams {
  double stiffness = 0;  // k_t, N/m; 0: none fitted (render the proxy's spring)
  double damping = 0;    // b, N·s/m
  double offset = 0;     // a, N
  bool ok() const {
    return std::isfinite(stiffness) && std::isfinite(damping) && std::isfinite(offset) &&
           stiffness > 0 && damping >= 0;
  }
};

class ViscoelasticFit {
 public:
  static constexpr double kTimeConstantS = 0.5;  // the samples' weight halves in ~0.35 s
  static constexpr double kWindowS = 0.008;      // the shortest window an Ṡ is taken over
  static constexpr double kMinYieldSpreadM = 0.2e-3;
  static constexpr double kMinRateSpreadMPerS = 2e-3;
  // A window whose yield moved faster than this is a jump, not the tissue: a deformation thread
  // starved of CPU publishing many steps at once, or the proxy crossing a ridge. Such a window
  // teaches the fit nothing and leaves the rate as it was (measured beside two CPU hogs: windows
  // at −0.3 to −1.4 m/s made the station's e₀ 3–14 N off a 0.3–0.5 N force).
  static constexpr double kMaxRateMPerS = 0.25;
  static constexpr double kRateTimeConstantS = 0.01;  // the rate's smoothing

  // A new contact: the window restarts (the sums and the last fit carry on: the same tissue).
  void BeginContact() { count_ = 0, rate_ = 0, has_rate_ = false; }

  // One sample in contact at time t (s): the surface's yield (m) and the force (N) along the
  // contact's rest normal. Non-finite values are ignored. k_t must lie in [min_stiffness,
  // max_stiffness] (N/m) for a fit to stand.
  void Add(double t_s, double yield_m, double force_n, double max_stiffness,
           double min_stiffness = 0) {
    if (!std::isfinite(t_s) || !std::isfinite(yield_m) || !std::isfinite(force_n)) return;
    if (count_ > 0 && !(t_s > ring_[(count_ - 1) % kRing].t)) return;  // time must advance
    // The newest earlier sample at least a window back (a copy: its slot may be the one this
    // sample takes).
    Sample back;
    bool found = false;
    for (uint32_t k = 1; k <= std::min<uint32_t>(count_, kRing) && !found; ++k) {
      back = ring_[(count_ - k) % kRing];
      found = t_s - back.t >= kWindowS;
    }
    const double since = count_ > 0 ? t_s - ring_[(count_ - 1) % kRing].t : 0.0;
    ring_[count_ % kRing] = Sample{t_s, yield_m, force_n};
    ++count_;
    if (!found || t_s - back.t > 0.1) return;  // no window, or a gap: nothing to learn
    const double dt = t_s - back.t;
    const double x1 = 0.5 * (yield_m + back.yield), x2 = (yield_m - back.yield) / dt;
    if (!(std::abs(x2) <= kMaxRateMPerS)) return;  // a jump (above)
    rate_ = has_rate_ ? rate_ + (1 - std::exp(-since / kRateTimeConstantS)) * (x2 - rate_) : x2;
    has_rate_ = true;
    const double y = 0.5 * (force_n + back.force);
    const double keep =
        last_t_ >= 0 ? std::exp(-std::clamp(t_s - last_t_, 0.0, 1.0) / kTimeConstantS) : 1.0;
    last_t_ = t_s;
    const double x[3] = {1, x1, x2};
    for (int p = 0; p < 3; ++p) {
      xy_[p] = keep * xy_[p] + x[p] * y;
      for (int q = 0; q < 3; ++q) xx_[p][q] = keep * xx_[p][q] + x[p] * x[q];
    }
    Solve(max_stiffness, min_stiffness);
  }

  // The last fit (stiffness 0 before any).
  const ViscoelasticParams& params() const { return fit_; }
  // The surface's yield rate over the last window, m/s (0 before one): with the force f now, the
  // tissue's elastic force is f − b·Ṡ, what the station's integration starts from.
  double rate() const { return rate_; }

  template <class A>
  void Persist(A& a) {
    a(ring_, count_, xx_, xy_, last_t_, rate_, has_rate_, fit_.stiffness, fit_.damping,
      fit_.offset);
  }

 private:
  struct Sample {
    double t = 0, yield = 0, force = 0;
    template <class A>
    void Persist(A& a) {
      a(t, yield, force);
    }
  };
  static constexpr uint32_t kRing = 64;

  void Solve(double max_stiffness, double min_stiffness) {
    const double w = xx_[0][0];
    if (!(w > 8)) return;
    // The weighted spreads of S and Ṡ: both must show, or the fit is a guess.
    const double var_s = xx_[1][1] / w - (xx_[0][1] / w) * (xx_[0][1] / w);
    const double var_r = xx_[2][2] / w - (xx_[0][2] / w) * (xx_[0][2] / w);
    if (!(var_s > kMinYieldSpreadM * kMinYieldSpreadM) ||
        !(var_r > kMinRateSpreadMPerS * kMinRateSpreadMPerS))
      return;
    // Cramer's rule on the 3×3 normal equations (symmetric, positive definite once spread).
    const auto det3 = [](const double m[3][3]) {
      return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
             m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
             m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    };
    const double det = det3(xx_);
    if (!(std::abs(det) > 0)) return;
    double sol[3];
    for (int c = 0; c < 3; ++c) {
      double m[3][3];
      for (int r = 0; r < 3; ++r)
        for (int q = 0; q < 3; ++q) m[r][q] = q == c ? xy_[r] : xx_[r][q];
      sol[c] = det3(m) / det;
    }
    ViscoelasticParams p{sol[1], sol[2], sol[0]};
    // A falling or absurd slope is a transient, not the tissue: keep the last fit. So is a
    // negative damping (a force that fell as the yield sped up): the windows of a deformation
    // thread starved of CPU, whose yield stalls while the force moves and then jumps. Taken as
    // b = 0 it told the station a tissue with no viscosity that springs back with the tool
    // (beside two CPU hogs one press in ten read k_t ≈ 8 N/m, b = 0, and the station pushed
    // 0.2-0.6 N on a tool 10 mm off the surface).
    // So is a tissue with next to no stiffness: a yield that creeps under a steady force (the
    // mass-spring ball held after a tap read k_t = 0.4 N/m, b = 1.7 N·s/m), which would tell the
    // station a tissue that follows the withdrawing tool with its whole force.
    if (!p.ok() || p.stiffness > max_stiffness || p.stiffness < min_stiffness || p.damping > 1000)
      return;
    fit_ = p;
  }

  Sample ring_[kRing] = {};
  uint32_t count_ = 0;
  double xx_[3][3] = {};
  double xy_[3] = {};
  double last_t_ = -1;  // s, the last window's end; < 0 before any
  double rate_ = 0;     // m/s, smoothed over kRateTimeConstantS
  bool has_rate_ = false;
  ViscoelasticParams fit_;
};

// The tissue's static curve under the proxy, where the scene measured it (`vsurg-sim
// contact-law`): the elastic force e(S) (N) at the yield S (m), piecewise linear through (0, 0)
// and up to kMaxPoints points of strictly rising yield and force, extended beyond both ends by
// the end segments' slopes. A ball's surface first yields stiffly and then at the ball's own
// slope, an elastic half-space stiffens (Hertz): neither is one line through the origin.
struct TissueCurve {
  static constexpr int kMaxPoints = 16;
  std::array<double, kMaxPoints> yield{}, force{};  // m, N
  int count = 0;                                    // 0: no curve

  // Strictly rising from (0, 0), finite, at most kMaxPoints: what a scene or a server may give.
  bool Valid() const {
    if (count < 1 || count > kMaxPoints) return false;
    double x = 0, f = 0;
    for (int i = 0; i < count; ++i) {
      if (!(yield[i] > x && force[i] > f && std::isfinite(yield[i]) && std::isfinite(force[i])))
        return false;
      x = yield[i], f = force[i];
    }
    return true;
  }
  // e(s), N.
  double Elastic(double s) const {
    int i = 0;
    while (i < count - 1 && s > yield[i]) ++i;
    const Segment g = SegmentOf(i);
    return g.force + g.slope * (s - g.yield);
  }
  // The yield σ (m) at which a·σ + e(σ) = rhs (a ≥ 0, N/m; rhs, N): h(σ) = a·σ + e(σ) rises
  // strictly, so the first segment whose end h passes rhs holds it.
  double Solve(double a, double rhs) const {
    int i = 0;
    while (i < count - 1 && a * yield[i] + force[i] <= rhs) ++i;
    const Segment g = SegmentOf(i);
    return g.yield + (rhs - a * g.yield - g.force) / (a + g.slope);
  }

 private:
  struct Segment {
    double yield, force, slope;  // its start (m, N) and slope (N/m)
  };
  // Segment i runs from point i − 1 ((0, 0) for i = 0) to point i; the first and the last also
  // extend beyond.
  Segment SegmentOf(int i) const {
    const double x = i == 0 ? 0 : yield[i - 1], f = i == 0 ? 0 : force[i - 1];
    return {x, f, (force[i] - f) / (yield[i] - x)};
  }
};

class ViscoelasticContact {
 public:
  // Starts from an answer: its force along n (f₀, N), the proxy's spring (k_p, N/m), the tissue
  // (k_t, b) and its elastic force then (e₀, N). σ = 0 at the answered sample.
  // The viscous force the answer starts with, f₀ − e₀, is taken at most as half the force: the
  // station does not trust a rate that a starved server measured over a jump.
  // With a curve (valid, outliving the contact) the tissue's elastic force is e₀ + e(σ) in place
  // of e₀ + k_t·σ: a contact begun at the rest surface (f₀ = e₀ = 0) follows the static curve.
  void Begin(double f0, double kp, double kt, double b, double e0,
             const TissueCurve* curve = nullptr) {
    const double viscous = std::clamp(f0 - e0, -0.5 * std::abs(f0), 0.5 * std::abs(f0));
    f0_ = f0, kp_ = kp, kt_ = kt, b_ = b, e0_ = f0 - viscous, sigma_ = 0;
    curve_ = curve && curve->Valid() ? curve : nullptr;
  }
  // One step of dt (s) to the tool's advance u (m along −n since the answered sample); returns
  // the force along n (N, ≥ 0).
  double Step(double u, double dt) {
    if (!(dt > 0) || !std::isfinite(u)) return Force(u);
    const double c = b_ / dt;
    // In contact: b(σ' − σ)/dt = f₀ + k_p(u − σ') − e₀ − e(σ'), e(σ) = k_t·σ or the curve's.
    const auto solve = [&](double a, double rhs) {
      return curve_ ? curve_->Solve(a, rhs) : rhs / (a + kt_);
    };
    double next = solve(c + kp_, c * sigma_ + f0_ + kp_ * u - e0_);
    if (f0_ + kp_ * (u - next) <= 0) next = solve(c, c * sigma_ - e0_);  // free: recovers
    if (std::isfinite(next)) sigma_ = next;
    return Force(u);
  }
  // Never above the stiffer of the solid's two linear responses from the answer (k_p at once, the
  // series spring k_p·k_t/(k_p + k_t) once relaxed) by more than the viscous force it started
  // with: a bound on what any error in the answer's state can push the hand with. Below, the
  // tissue's own path rules (after a press, a withdrawal unloads at k_p from the yielded state).
  double Force(double u) const {
    const double at_once = f0_ + kp_ * u, relaxed = f0_ + kp_ * kt_ / (kp_ + kt_) * u;
    const double f =
        std::min(f0_ + kp_ * (u - sigma_), std::max(at_once, relaxed) + std::abs(f0_ - e0_));
    return std::isfinite(f) ? std::max(0.0, f) : 0.0;
  }
  double sigma() const { return sigma_; }

 private:
  double f0_ = 0, kp_ = 0, kt_ = 0, b_ = 0, e0_ = 0, sigma_ = 0;
  const TissueCurve* curve_ = nullptr;
};

}  // namespace vsurg::haptics
