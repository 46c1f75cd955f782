// Ring-layer reduced model for palpation (the mass-spring paper §3.3).
//
// Around the contact point the surface is cut into concentric rings of radius r, 2r, 3r, …
// (ring k holds the particles whose distance ρ from the contact rounds to k·r); the particles of
// one ring move together, and neighbouring rings are joined by equal springs. What is left is a
// 1-D chain of K+1 ring masses along the press direction: ring 0 is the contact, ring K is the
// fixed boundary beyond which nothing moves. Optionally each ring is also tethered to its rest
// place (the tissue underneath), stiffness per particle.
//
// Chain (u_k displacement along the press direction, m; v_k its rate):
//   m_k ü_k = k_c (u_{k−1} − 2u_k + u_{k+1}) + c_c (v_{k−1} − 2v_k + v_{k+1}) − t_k u_k + f_k
// integrated by backward Euler, which for this linear system is one tridiagonal solve per step
// (Thomas algorithm, O(K), stable at any step). The mesh follows: x = x_rest + u(ρ)·d̂ with u(ρ)
// linear between ring radii, only for vertices with ρ < K·r.
//
// Units: m, kg, s, N. Threads: one model per thread; Step and Apply never allocate.
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::tissue {

struct RingLayerParams {
  double ring_spacing = 0.005;    // r, m
  int rings = 8;                  // K: ring K (at K·r) is fixed
  double chain_stiffness = 50.0;  // k_c, N/m between neighbouring rings
  double chain_damping = 0.05;    // c_c, N·s/m between neighbouring rings
  double tether_stiffness = 0.0;  // N/m per particle, each ring to its rest place
};

class RingLayerModel {
 public:
  // rest: the mesh positions; distance: ρ of every vertex from the contact (m; +inf allowed);
  // masses: per vertex (kg); press_direction: the direction the contact is pushed (normalised).
  // Every ring 0..K−1 must hold at least one vertex (else: make the spacing larger).
  static Expected<RingLayerModel> Create(const std::vector<geometry::Vec3>& rest,
                                         const std::vector<double>& distance,
                                         const std::vector<double>& masses,
                                         const geometry::Vec3& press_direction,
                                         const RingLayerParams& params);

  // Drive the contact ring: to a displacement (m) reached at the end of the next step, or by a
  // force (N) along the press direction. The last call decides.
  void SetContactDisplacement(double u);
  void SetContactForce(double f);

  // Backward Euler over dt (s); false on a non-finite input (state unchanged).
  bool Step(double dt);
  // The equilibrium for the current drive (a tridiagonal solve), velocities zero.
  void SolveStatic();
  // Moves the mesh vertices inside the rings; returns how many it wrote.
  int Apply();

  // The force the tissue pushes back on the tool with, along −press direction (N, ≥ 0 when
  // pressed in): the chain spring, damper and tether on ring 0, plus its inertia when driven.
  double ContactForce() const { return contact_force_; }
  const std::vector<double>& displacements() const { return u_; }   // u_k, m
  const std::vector<double>& ring_masses() const { return mass_; }  // m_k, kg
  const std::vector<geometry::Vec3>& positions() const { return deformed_; }
  double PotentialEnergy() const;  // J
  double KineticEnergy() const;    // J
  // The rings' motion (common/core/state_archive.h); the rings themselves come from Create.
  template <class A>
  void Persist(A& a) {
    a(u_, v_, drive_by_displacement_, drive_, contact_force_, deformed_);
  }

 private:
  RingLayerModel() = default;
  void Solve(double h);  // h = 0: statics

  RingLayerParams params_;
  geometry::Vec3 dir_ = geometry::Vec3::UnitZ();
  std::vector<double> mass_, tether_, u_, v_;
  bool drive_by_displacement_ = true;
  double drive_ = 0;  // m or N
  double contact_force_ = 0;
  // Vertices inside the rings: index, ring below and fraction towards the next.
  std::vector<int> vertex_;
  std::vector<int> ring_;
  std::vector<double> frac_;
  std::vector<geometry::Vec3> rest_, deformed_;
  std::vector<double> sub_, diag_, sup_, rhs_, u_prev_;  // scratch, sized at Create
};

}  // namespace vsurg::tissue
