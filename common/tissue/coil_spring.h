// Coil-spring torsion model (the coil-spring paper §1, as DESIGN.md "Model 1" reads it).
//
// Soft tissue twisted by a torque M is a chain of S concentric coils around a rigid core of
// radius r. Coil i (i = 1..S) has radius R_i = r + i·h, a rectangular section of thickness h and
// width b, and can carry at most C_i = 2π·R_i·F_t of torque. A torque fills the coils from the
// inside out; the first coil that is not full is the cutoff layer P, and coils beyond it do not
// move. Each coil twists by φ_i = κ·M_i·l_i / (E·I), and the twist angle at distance ρ from the
// grasp is the sum of the twists of the coils outside ρ.
//
// Legend (SI): r core radius [m]; h coil thickness [m]; b coil width [m]; S coil count;
// E elastic modulus [Pa]; I = b·h³/12 second moment of the coil section [m⁴]; F_t maximum
// force per coil point [N] (so that C_i = l_i·F_t is a torque [N·m]); κ friction factor (1.25 in
// the paper); M torque [N·m]; n_i twisted turns [1]; φ_i = 2π·n_i twist of coil i [rad].
//
// Beyond the paper: each coil may carry its own flexural rigidity E·I_i (the per-ring
// calibration in coil_calibration.h fits them); left empty, every coil has E·b·h³/12.
//
// Threads: a model is immutable after Create and may be shared by any number of threads.
// Forward() and Inverse() never allocate when given a state made by MakeState(); they are the
// calls of the haptic loop.
#pragma once

#include <vector>

#include "common/core/expected.h"

namespace vsurg::tissue {

struct CoilSpringParams {
  double core_radius = 0.02;  // r, m
  double thickness = 0.01;    // h, m
  double width = 0.05;        // b, m
  int coils = 23;             // S
  double modulus = 35.3e3;    // E, Pa (E = 2G(1+ν), G = 12 kPa, ν = 0.47)
  double max_force = 0.163;   // F_t, N
  double friction = 1.25;     // κ (the coil-spring paper eq. 6)
  // Optional per-coil flexural rigidity E·I_i in N·m², size S; empty → E·b·h³/12 for all.
  std::vector<double> coil_rigidity;
};

// Result of a forward evaluation. The arrays are sized for S coils when made by MakeState();
// only the first P (coil arrays) and P+1 (boundary angles) entries are meaningful.
struct CoilState {
  double requested_torque = 0;          // N·m, as asked
  double torque = 0;                    // N·m, applied: the request clamped to ±capacity
  int cutoff = 0;                       // P, the cutoff layer; 0 when the torque is zero
  bool overload = false;                // |request| exceeded the capacity Σ C_i and was clamped
  bool invalid_input = false;           // the request was NaN or infinite; treated as zero
  double total_twist = 0;               // Φ = Σ φ_i = Θ_0, rad
  std::vector<double> coil_torques;     // M_i, N·m, i = 1..P at [i−1]
  std::vector<double> twist_turns;      // n_i, turns
  std::vector<double> twist_angles;     // φ_i, rad
  std::vector<double> boundary_angles;  // Θ_k, rad, k = 0..P at [k]; Θ_0 = Φ, Θ_P = 0
};

// Result of an inverse query: the torque the tissue answers to an imposed twist.
struct CoilTorque {
  double torque = 0;           // N·m, same sign as the twist
  double stiffness = 0;        // dM/dΦ, N·m/rad; 0 past capacity (the torque no longer grows)
  int cutoff = 0;              // P at that torque
  bool overload = false;       // |twist| exceeded the twist at full capacity
  bool invalid_input = false;  // the twist was NaN or infinite; the answer is zero torque
};

class CoilSpringModel {
 public:
  // Validates the parameters (every length, E, F_t, κ finite and > 0; 1 ≤ S ≤ kMaxCoils; each
  // E·I_i finite and > 0) and precomputes the cumulative arrays. The error names the field.
  static Expected<CoilSpringModel> Create(const CoilSpringParams& params);

  static constexpr int kMaxCoils = 10000;

  // the coil-spring paper eq. 3–7. Any thread; no allocation when `out` came from MakeState().
  void Forward(double torque, CoilState& out) const;
  CoilState Forward(double torque) const;
  CoilState MakeState() const;

  // Closed-form inverse of Φ(M): binary search for the segment, then linear. Any thread; never
  // allocates; O(log S).
  CoilTorque Inverse(double twist) const;

  // Twist angle (rad) at distance ρ (m) from the grasp for an evaluated state: Φ inside the
  // core, linear in each ring between its boundary angles, zero beyond R_P.
  double TwistAt(double rho, const CoilState& state) const;

  int coils() const { return params_.coils; }
  const CoilSpringParams& params() const { return params_; }
  double RingRadius(int i) const { return ring_radius_[i]; }    // R_i, i = 0..S (R_0 = r)
  double CoilCapacity(int i) const { return capacity_[i]; }     // C_i, i = 1..S
  double Capacity() const { return cum_capacity_.back(); }      // Σ C_i, N·m
  double TwistAtCapacity() const { return cum_twist_.back(); }  // Φ(Σ C_i), rad
  double CoilRigidity(int i) const { return rigidity_[i]; }     // E·I_i, N·m², i = 1..S
  // dΦ/dM on segment p (p = 1..S): κ·2π·R_p / (E·I_p), rad/(N·m).
  double SegmentCompliance(int p) const { return segment_compliance_[p]; }

 private:
  CoilSpringParams params_;
  // Index 0 is the core (or unused) so coil i lives at [i], as in the paper.
  std::vector<double> ring_radius_;         // R_i
  std::vector<double> capacity_;            // C_i = 2π·R_i·F_t
  std::vector<double> cum_capacity_;        // Q_p = Σ_{i≤p} C_i, Q_0 = 0
  std::vector<double> rigidity_;            // E·I_i
  std::vector<double> segment_compliance_;  // κ·2π·R_p/(E·I_p)
  std::vector<double> cum_twist_;           // Φ at M = Q_p: Σ_{i≤p} κ·C_i·2πR_i/(E·I_i)
};

}  // namespace vsurg::tissue
