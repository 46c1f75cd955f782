// Passivity observer and controller (Hannaford & Ryu 2002, "Time-domain passivity control of
// haptic interfaces"), for a force held by a zero-order hold.
//
// A device outputs the force F_k computed at cycle k for the whole servo interval that follows,
// until F_{k+1} replaces it; over that interval the hand moves from x_k to x_{k+1}. The energy
// the hand really exchanged with the environment is therefore
//   E_k = −Σ_{j<k} F_j · (x_{j+1} − x_j)        (J; > 0: absorbed by the environment)
// which pairs each force with the motion *after* it. Pairing F_k with the step *into* x_k
// instead (F_k·(x_k − x_{k−1})) reads a sampled spring under tremor as absorbing when it is in
// fact giving the hand energy (Σ k·Δx²/2 per cycle); that was this observer's first version.
// A passive environment keeps E ≥ 0. When E < 0, the controller adds to the force about to be
// held the damping α = −(E + E₀)/(|v|²·Δt) along the latest velocity v, capped at max_damping,
// which dissipates the excess if the hand keeps moving as it did; the next observation measures
// what it really dissipated. E₀ (reserve, default 0.1 mJ) is the initial energy of the passivity
// definition E(t) ≥ −E₀: without it the controller acts on every sampled spring's sliver (a
// 200 N/m spring under a 1 cm, 2 Hz stroke returns ~25 µJ more than it took per half stroke),
// damping hardest where the hand moves fastest; with it, it acts only on energy that adds up.
//
// In free space (a zero request) the balance restarts at zero: nothing is stored there, and a
// controller that damped a free hand to settle an old debt would be felt as drag.
//
// The velocity the controller damps is the mean over the last kVelocityWindow intervals, not the
// last step: a Touch-class encoder counts 0.055 mm, so one count in one 1 ms interval reads as
// 55 mm/s, and the maximum damping on that gave a 0.27 N kick whose own work, against the next
// count's reversal, read as energy given: a 250 Hz buzz that fed itself (the forceps scene's
// chatter). Over 8 ms a count reads as 7 mm/s and a flip-flop averages to nothing.
//
// A model that is not conservative in x on purpose may declare what it may legitimately give the
// hand: `allowance` (J, ≥ 0) lowers the floor to −(E₀ + allowance). The grasp's twist is rendered
// on a 3-DoF device as a force field F_φ that grows with the stylus's turn (an input port the
// device cannot feel), so a hand yielding to it is given up to |F_φ|²/(2k) against the hold
// spring k: that is the grasp's design, present without any delay, not energy the loop made.
//
// Call order per servo cycle: Apply(f, x, dt) with the position read now and the force asked for
// the coming interval, then Held(out) with the force actually written (after the safety filter).
// Threads: one per device loop; no allocation. Units: N, m, s, J, N·s/m.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

namespace vsurg::client {

class PassivityController {
 public:
  // max_damping 0: observe only.
  explicit PassivityController(double max_damping = 5.0, double reserve_j = 1e-4)
      : max_damping_(max_damping), reserve_(reserve_j) {}

  Eigen::Vector3d Apply(const Eigen::Vector3d& force, const Eigen::Vector3d& position, double dt,
                        double allowance = 0) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (position.allFinite()) {
      if (has_last_) {
        const Eigen::Vector3d step = position - last_x_;
        const double w = held_.dot(step);  // work the held force did on the hand
        energy_ -= w;
        (w > 0 ? to_hand_ : from_hand_) += std::abs(w);
      }
      last_x_ = position;
      has_last_ = true;
      // The mean velocity over the window (fewer intervals while it fills).
      window_[head_ % kWindow] = position;
      ++head_;
      const int intervals = static_cast<int>(std::min<uint64_t>(head_ - 1, kVelocityWindow));
      if (intervals > 0 && dt > 0)
        v = (position - window_[(head_ - 1 - intervals) % kWindow]) / (intervals * dt);
    } else {
      head_ = 0;  // a gap in the readings: the window starts again
    }
    Eigen::Vector3d f = force.allFinite() ? force : Eigen::Vector3d::Zero();
    if (f.isZero(0.0)) {
      // Free space (or the watchdog's fade has ended): the environment holds no energy, so its
      // balance starts afresh at the next contact (Ryu et al. 2004) instead of the controller
      // dragging a free hand to settle an old account. The totals below keep the whole record.
      energy_ = 0;
      held_ = f;
      return f;
    }
    const double v2 = v.squaredNorm();
    const double floor = reserve_ + (std::isfinite(allowance) ? std::max(0.0, allowance) : 0.0);
    if (energy_ + floor < 0 && v2 > 1e-12 && dt > 0 && max_damping_ > 0) {
      const double alpha = std::min(max_damping_, -(energy_ + floor) / (v2 * dt));
      f -= alpha * v;
      dissipated_ += alpha * v2 * dt;
    }
    held_ = f;
    return f;
  }
  // The force actually output for the interval Apply began (after any later filter).
  void Held(const Eigen::Vector3d& out) { held_ = out.allFinite() ? out : Eigen::Vector3d::Zero(); }

  double energy() const { return energy_; }          // J absorbed by the environment so far
  double to_hand() const { return to_hand_; }        // J of positive work on the hand
  double from_hand() const { return from_hand_; }    // J the hand put in
  double dissipated() const { return dissipated_; }  // J the controller meant to remove

  static constexpr int kVelocityWindow = 8;  // servo intervals

 private:
  static constexpr int kWindow = kVelocityWindow + 1;
  double max_damping_, reserve_;
  Eigen::Vector3d window_[kWindow];
  uint64_t head_ = 0;
  double energy_ = 0, to_hand_ = 0, from_hand_ = 0, dissipated_ = 0;
  Eigen::Vector3d held_ = Eigen::Vector3d::Zero(), last_x_ = Eigen::Vector3d::Zero();
  bool has_last_ = false;
};

}  // namespace vsurg::client
