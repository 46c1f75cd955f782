// Proxy (god-object) contact: Zilles & Salisbury 1995; the mass-spring paper §2.3's HIP and SCP.
//
// The haptic interface point (HIP, the stylus tip) may sink into the tissue; the surface contact
// point (SCP, the proxy) stays on the surface. Contact starts when the segment from the previous
// tip to the new one enters the surface through an outward face, so a fast stroke cannot tunnel
// through; while in contact the proxy moves to the surface point closest to the tip among faces
// that keep facing the way the contact face did (n·n_prev ≥ min_normal_dot), so pushing through a
// thin sheet never pops the proxy to the far side, and by at most max_step per update. Contact
// ends when the tip is back outside; it also starts when a deforming surface moves over a
// resting tip (the tip lies within max_step under its closest face). The force is the mass-spring
// paper's spring-damper, F = K·x + D·ẋ with x = SCP − HIP; optional Coulomb friction keeps the
// proxy where it is while the tangential force stays inside the cone μ·|F_n|.
//
// Local model: in contact F ≈ F₀ − K n nᵀ (x − x₀) (sliding along the face costs nothing);
// free: zero.
//
// Threads: one proxy per haptic loop; Update never allocates (its kept lists are reserved).
// Units: m, s, N, N/m, N·s/m.
#pragma once

#include <limits>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/bvh.h"
#include "common/haptics/types.h"

namespace vsurg::haptics {

struct ProxyParams {
  double stiffness = 300.0;  // K, N/m
  double damping = 1.0;      // D, N·s/m
  double friction = 0.0;     // μ, Coulomb coefficient (0: frictionless)
  double max_step = 0.01;    // m the proxy may travel per update
  double min_normal_dot =
      0.0;  // faces turning more than 90° away from the contact face are skipped
};

struct ProxyState {
  bool contact = false;
  Vec3 scp = Vec3::Zero();      // m
  Vec3 normal = Vec3::UnitZ();  // outward unit normal at the SCP (valid in contact)
  int triangle = -1;
  Vec3 barycentric = Vec3::Zero();
  double penetration = 0;                              // m, (SCP − HIP)·n, ≥ 0 in contact
  Vec3 force = Vec3::Zero();                           // N, before device limits
  Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();  // N/m
  template <class A>
  void Persist(A& a) {
    a(contact, scp, normal, triangle, barycentric, penetration, force, jacobian);
  }
};

class ProxyContact {
 public:
  static constexpr double kKeptListMargin = 5e-4;  // m, the kept face lists' (ClosestCache)
  static Expected<ProxyContact> Create(const ProxyParams& params);

  // One haptic update against a surface snapshot (positions and a BVH refitted to them).
  // surface_motion: the snapshot's geometry::ClosestCache motion bound (sim's Snapshot::motion);
  // with it the per-update closest-face queries answer from kept lists (the same distances,
  // fewer memory reads); unknown (+inf), each walks the tree.
  const ProxyState& Update(const std::vector<geometry::Vec3>& positions, const geometry::Bvh& bvh,
                           const Vec3& hip, double dt,
                           double surface_motion = std::numeric_limits<double>::infinity());
  void Reset();
  const ProxyState& state() const { return state_; }
  const ProxyParams& params() const { return params_; }
  // The contact's state (common/core/state_archive.h), not its parameters nor its kept lists
  // (made again after a restore: they belong to the surface they were made on).
  template <class A>
  void Persist(A& a) {
    contact_faces_.Clear();
    free_faces_.Clear();
    a(state_, last_hip_, has_last_, last_x_);
  }

 private:
  explicit ProxyContact(const ProxyParams& p) : params_(p) {}
  ProxyParams params_;
  ProxyState state_;
  Vec3 last_hip_ = Vec3::Zero();
  bool has_last_ = false;
  Vec3 last_x_ = Vec3::Zero();  // previous SCP − HIP, for ẋ
  // The two queries made on every update: in contact, the closest accepted face to the tip; free,
  // the closest face within max_step (a surface moving over a resting tip). A 0.5 mm margin: the
  // fastest of those measured for a hand's speeds (docs/BENCHMARKS.md, BM_ProxyQuery).
  geometry::ClosestCache contact_faces_{kKeptListMargin}, free_faces_{kKeptListMargin};
};

}  // namespace vsurg::haptics
