// Passivity observer and controller (Hannaford & Ryu 2002, "Time-domain passivity control of
// haptic interfaces").
//
// The observer integrates the energy the rendered force has taken out of the hand,
// E = −Σ F·v·Δt (F the force on the hand, v its velocity). A passive virtual environment keeps
// E ≥ 0: it can give back no more than it was given. When E < 0 the coupling has generated
// energy (a stale or extrapolated local model, a stiff spring sampled too slowly); the
// controller then adds the damping α = −E/(|v|²Δt) for that sample, capped at max_damping, which
// dissipates exactly the excess.
//
// Threads: one per device loop; no allocation. Units: N, m/s, s, J, N·s/m.
#pragma once

#include <algorithm>

#include <Eigen/Core>

namespace vsurg::client {

class PassivityController {
 public:
  explicit PassivityController(double max_damping = 5.0) : max_damping_(max_damping) {}

  Eigen::Vector3d Apply(const Eigen::Vector3d& force, const Eigen::Vector3d& velocity, double dt) {
    if (!force.allFinite() || !velocity.allFinite() || !(dt > 0))
      return force.allFinite() ? force : Eigen::Vector3d::Zero();
    Eigen::Vector3d f = force;
    energy_ -= f.dot(velocity) * dt;
    const double v2 = velocity.squaredNorm();
    if (energy_ < 0 && v2 > 1e-12) {
      const double alpha = std::min(max_damping_, -energy_ / (v2 * dt));
      f -= alpha * velocity;
      energy_ += alpha * v2 * dt;
      dissipated_ += alpha * v2 * dt;
    }
    return f;
  }

  double energy() const { return energy_; }          // J absorbed by the environment so far
  double dissipated() const { return dissipated_; }  // J the controller removed

 private:
  double max_damping_;
  double energy_ = 0;
  double dissipated_ = 0;
};

}  // namespace vsurg::client
