// MassSpringModel's topology changes (mass_spring.h): particles added as copies of others and
// springs moved between them, within room reserved at set-up, so that a cut made on the
// deformation thread never allocates. Every change marks the solver's derived arrays stale: the
// springs with a free end are selected again and the diagonal summed again on the next step.
#include <cmath>

#include "common/tissue/mass_spring.h"

namespace vsurg::tissue {

void MassSpringModel::ReserveParticles(int capacity) {
  const size_t n = static_cast<size_t>(std::max(capacity, 0));
  sys_.rest_positions.reserve(n), sys_.masses.reserve(n);
  role_.reserve(n), inv_mass_.reserve(n);
  for (auto* buf : {&x_, &v_, &f_ext_, &kin_start_, &kin_target_, &a_, &tx_, &tv_, &k1v_, &k2x_,
                    &k2v_, &k3x_, &k3v_, &kin_final_})
    buf->reserve(n);
  for (auto* buf : {&dv_, &r_, &p_, &q_, &precond_, &pos_, &diag_, &inv_diag_, &history_[0],
                    &history_[1], &history_[2], &history_[3]})
    buf->reserve(n);
  state_.reserve(n), sums_.reserve(n);
  constrained_.reserve(n), kinematic_.reserve(n);
}

int MassSpringModel::SplitParticle(int of, double mass) {
  const size_t n = x_.size();
  if (of < 0 || static_cast<size_t>(of) >= n || !(std::isfinite(mass) && mass > 0)) return -1;
  if (n >= x_.capacity() || n >= history_[3].capacity() || n >= sums_.capacity()) return -1;
  sys_.rest_positions.push_back(sys_.rest_positions[of]);
  sys_.masses.push_back(mass);
  role_.push_back(role_[of]);
  inv_mass_.push_back(1.0 / mass);
  x_.push_back(x_[of]), v_.push_back(v_[of]);
  f_ext_.push_back(Vec3::Zero());
  kin_start_.push_back(kin_start_[of]), kin_target_.push_back(kin_target_[of]);
  for (auto* buf : {&a_, &tx_, &tv_, &k1v_, &k2x_, &k2v_, &k3x_, &k3v_, &kin_final_})
    buf->push_back(Vec3::Zero());
  for (auto* buf : {&dv_, &r_, &p_, &q_, &precond_, &pos_, &diag_, &inv_diag_, &history_[0],
                    &history_[1], &history_[2], &history_[3]})
    buf->push_back(simd::Lane4{});
  state_.push_back(simd::Lane8{}), sums_.push_back(simd::Lane8{});
  const int id = static_cast<int>(n);
  if (role_[of] == Role::kKinematic) kinematic_.push_back(id);
  solver_springs_stale_ = true;
  lanes_ = false;
  verlet_primed_ = false;
  diag_age_ = kDiagEvery;
  return id;
}

void MassSpringModel::SetMass(int i, double mass) {
  if (i < 0 || static_cast<size_t>(i) >= x_.size() || !(std::isfinite(mass) && mass > 0)) return;
  sys_.masses[i] = mass;
  inv_mass_[i] = 1.0 / mass;
  diag_age_ = kDiagEvery;
}

void MassSpringModel::SetSpring(size_t s, int i, int j, double rest_length) {
  const int n = static_cast<int>(x_.size());
  if (s >= sys_.springs.size() || i < 0 || j < 0 || i >= n || j >= n || i == j) return;
  if (!(std::isfinite(rest_length) && rest_length >= 0)) return;
  Spring& sp = sys_.springs[s];
  sp.i = i, sp.j = j, sp.rest_length = rest_length;
  solver_springs_stale_ = true;
  verlet_primed_ = false;
}

void MassSpringModel::SetRestPosition(int i, const Vec3& rest) {
  if (i < 0 || static_cast<size_t>(i) >= x_.size() || !rest.allFinite()) return;
  sys_.rest_positions[i] = rest;
}

}  // namespace vsurg::tissue
