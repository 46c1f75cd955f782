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
// Across a network the coupling is a two-port, and the delayed channel itself can be active:
// the station's local model can hand back energy the tissue has not released (yet, or at all).
// kNetwork is the two-port's station side after the time-domain passivity network of Ryu,
// Artigas & Preusche (2010) and Artigas et al. (2011). The server reports with every answer its
// port's energies through the stylus sample it answers (sequence s): what its force gave the
// tool, E_S,in (released_j), and took from it, E_S,out (absorbed_j), sums of F·Δx by sign over
// the samples it received. The station remembers its own port's flows as of each sample it sent,
// E_M,in(s) and E_M,out(s), and keeps the net energy it gives the hand, N_M = E_M,out − E_M,in,
// within what the tissue's net, N_S = E_S,in − E_S,out, allows at the same sample; what the hand
// has put in since s offsets only what it has been given since (it may get back its own energy
// still on its way to the tissue, never bank it as credit):
//   max(0, N_M(k) − N_M(s)) ≤ N_S(s) − N_M(s) + E₀ + 2·|F|·q
// i.e. the hand is never given more, net, than the tissue gave the tool by the same sample plus
// what the hand itself put in within the last round trip (tests/client/net/passivity_test.cpp
// measures both against the one-port: 0.19 against 0.56 mJ ahead of a 300 ms record). q is
// the device's resolution (the smallest step it has reported): one count each way at the force
// held is what a trembling hand's readings alone add between two reports. Net flows, not TDPN's
// monotone sums (E_M,out ≤ E_S,in): the sums' positive parts grow with every count the hand
// trembles across (+F·q, −F·q, …) at a rate set by each side's own force, and two forces a few
// percent apart drained the reserve within tens of milliseconds: that version chattered on the
// arm even on loopback (docs/BENCHMARKS.md). It is enforced on the coming interval's predicted work
// (energy bounding: the force's part along the motion is cut, never reversed; a capped damper,
// ≤ 5 N·s/m, cannot hold back a spring pushing a slow hand). The cost is transparency: after a
// press, the surface's push back is cut until the server's record of the release arrives, one
// round trip later; and where the hand yields to a grasp's twist field all along (the arm, the
// forceps), the budget hovers at zero and the cut chatters from a 20 ms round trip on (BENCHMARKS:
// 0.13–0.31 N above 30 Hz). So kLocal, the one-port observer above, is the default.
// A session re-placed on another server starts that server's counts at zero: a report below the
// last one (answers arrive in order; stale ones are never applied) continues from the totals. A
// report about a sample older than the last kHistory sent is not used (the last one stands).
//
// Call order per servo cycle: TissueReport(…) with the newest answer, Apply(f, x, dt) with the
// position read now and the force asked for the coming interval, Held(out) with the force actually
// written (after the safety filter), and Sent(sequence) if a stylus sample went out.
// Threads: one per device loop; no allocation. Units: N, m, s, J, N·s/m.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

namespace vsurg::client {

enum class PassivityMode { kLocal, kNetwork };

class PassivityController {
 public:
  // max_damping 0: observe only.
  explicit PassivityController(double max_damping = 5.0, double reserve_j = 1e-4,
                               PassivityMode mode = PassivityMode::kLocal)
      : max_damping_(max_damping), reserve_(reserve_j), mode_(mode) {}

  // kNetwork: the stylus sample `sequence` was sent this cycle (after Apply).
  void Sent(uint64_t sequence) {
    Flows& h = history_[sequence % kHistory];
    h.sequence = sequence, h.to_hand = to_hand_, h.from_hand = from_hand_;
  }
  // kNetwork: the newest in-order answer, to stylus sample `echo_sequence`, with the server's port
  // energies through it (J, E_S,in and E_S,out).
  void TissueReport(uint64_t echo_sequence, double released_j, double absorbed_j) {
    if (!(released_j >= 0) || !std::isfinite(released_j) || !(absorbed_j >= 0) ||
        !std::isfinite(absorbed_j))
      return;
    const Flows& h = history_[echo_sequence % kHistory];
    if (h.sequence != echo_sequence) return;  // not sent by us, or long ago: the last stands
    if (released_j < last_released_ || absorbed_j < last_absorbed_) {  // another server's count
      released_base_ += last_released_;
      absorbed_base_ += last_absorbed_;
    }
    last_released_ = released_j, last_absorbed_ = absorbed_j;
    released_ = released_base_ + released_j;
    absorbed_ = absorbed_base_ + absorbed_j;
    surplus_ = (released_ - absorbed_) - (h.to_hand - h.from_hand);
    net_at_report_ = h.to_hand - h.from_hand;
  }

  Eigen::Vector3d Apply(const Eigen::Vector3d& force, const Eigen::Vector3d& position, double dt,
                        double allowance = 0) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (position.allFinite()) {
      if (has_last_) {
        const Eigen::Vector3d step = position - last_x_;
        const double w = held_.dot(step);  // work the held force did on the hand
        for (int a = 0; a < 3; ++a)
          if (const double d = std::abs(step[a]); d > 1e-9 && (count_ == 0 || d < count_))
            count_ = d;
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
    if (mode_ == PassivityMode::kNetwork) {
      // The two-port's account is never reset. What the force would give the hand over the
      // coming interval, F·v·Δt, may not exceed what is left of the tissue's release: beyond it,
      // the force's part along the motion is cut, to nothing at most (never reversed: a contact
      // that only pushes never pulls the tool in to settle the account), however slow the hand.
      // A free hand is never touched (nothing is output).
      // One encoder count each way at this force is what a trembling hand's readings alone make
      // of the account between two reports; the reserve covers it, so a count is never a cut.
      const double budget = std::max(0.0, network_balance() + reserve_ + 2 * f.norm() * count_);
      const double speed = v.norm();
      if (speed > 1e-9 && dt > 0 && max_damping_ > 0) {
        const Eigen::Vector3d dir = v / speed;
        const double along = f.dot(dir);
        const double excess = along * speed * dt - budget;
        if (along > 0 && excess > 0) {
          const double cut = std::min(along, excess / (speed * dt));
          f -= cut * dir;
          dissipated_ += cut * speed * dt;
        }
      }
      held_ = f;
      return f;
    }
    if (f.isZero(0.0)) {
      // Free space (or the watchdog's fade has ended): the environment holds no energy, so its
      // balance starts afresh at the next contact (Ryu et al. 2004) instead of the controller
      // dragging a free hand to settle an old account. The totals below keep the whole record.
      energy_ = 0;
      held_ = f;
      return f;
    }
    const double floor = reserve_ + (std::isfinite(allowance) ? std::max(0.0, allowance) : 0.0);
    held_ = f;
    return Damp(f, v, dt, energy_ + floor);
  }
  // The force actually output for the interval Apply began (after any later filter).
  void Held(const Eigen::Vector3d& out) { held_ = out.allFinite() ? out : Eigen::Vector3d::Zero(); }

  double energy() const { return energy_; }          // J absorbed by the environment so far
  double to_hand() const { return to_hand_; }        // J of positive work on the hand
  double from_hand() const { return from_hand_; }    // J the hand put in
  double dissipated() const { return dissipated_; }  // J the controller meant to remove
  double released() const { return released_; }      // kNetwork: the tissue's E_S,in so far
  // The tissue's net at the report's sample less the hand's, less what the hand has been given net
  // since (its input since offsets that, and is never banked as credit). J; < 0: given too much.
  double network_balance() const {
    return surplus_ - std::max(0.0, (to_hand_ - from_hand_) - net_at_report_);
  }
  double absorbed() const { return absorbed_; }  // kNetwork: the tissue's E_S,out so far

  static constexpr int kVelocityWindow = 8;   // servo intervals
  static constexpr uint64_t kHistory = 4096;  // samples sent (4 s at 1 kHz, more with a deadband)

 private:
  // The damping α = −balance/(|v|²·Δt) along v, capped, when the balance (J) is negative.
  Eigen::Vector3d Damp(Eigen::Vector3d f, const Eigen::Vector3d& v, double dt, double balance) {
    const double v2 = v.squaredNorm();
    if (balance < 0 && v2 > 1e-12 && dt > 0 && max_damping_ > 0) {
      const double alpha = std::min(max_damping_, -balance / (v2 * dt));
      f -= alpha * v;
      dissipated_ += alpha * v2 * dt;
    }
    held_ = f;
    return f;
  }

  static constexpr int kWindow = kVelocityWindow + 1;
  double max_damping_, reserve_;
  PassivityMode mode_;
  double released_ = 0, absorbed_ = 0, released_base_ = 0, absorbed_base_ = 0;
  double last_released_ = 0, last_absorbed_ = 0;
  double surplus_ = 0, net_at_report_ = 0;
  double count_ = 0;  // m, the smallest step the device has reported on any axis (its resolution)
  struct Flows {
    uint64_t sequence = ~uint64_t{0};
    double to_hand = 0, from_hand = 0;
  };
  Flows history_[kHistory];
  Eigen::Vector3d window_[kWindow];
  uint64_t head_ = 0;
  double energy_ = 0, to_hand_ = 0, from_hand_ = 0, dissipated_ = 0;
  Eigen::Vector3d held_ = Eigen::Vector3d::Zero(), last_x_ = Eigen::Vector3d::Zero();
  bool has_last_ = false;
};

}  // namespace vsurg::client
