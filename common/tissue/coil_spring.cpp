#include "common/tissue/coil_spring.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "common/tissue/text.h"

namespace vsurg::tissue {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

bool PositiveFinite(double x) {
  return std::isfinite(x) && x > 0;
}

using detail::Num;

// The smallest p in 1..S with cum[p] ≥ x, for 0 < x ≤ cum[S] (cum ascending, cum[0] = 0).
int FirstSegmentReaching(const std::vector<double>& cum, double x) {
  const auto it = std::lower_bound(cum.begin() + 1, cum.end(), x);
  return std::min(static_cast<int>(it - cum.begin()), static_cast<int>(cum.size()) - 1);
}

}  // namespace

Expected<CoilSpringModel> CoilSpringModel::Create(const CoilSpringParams& p) {
  struct Check {
    const char* field;
    double value;
    const char* what;
  };
  const Check checks[] = {
      {"core_radius", p.core_radius, "core radius r (m)"},
      {"thickness", p.thickness, "coil thickness h (m)"},
      {"width", p.width, "coil width b (m)"},
      {"modulus", p.modulus, "elastic modulus E (Pa)"},
      {"max_force", p.max_force, "maximum force per coil point F_t (N)"},
      {"friction", p.friction, "friction factor kappa"},
  };
  for (const Check& c : checks) {
    if (!PositiveFinite(c.value)) {
      return InvalidArgument(c.field,
                             std::string(c.what) + " must be finite and > 0, got " + Num(c.value));
    }
  }
  if (p.coils < 1 || p.coils > kMaxCoils) {
    return InvalidArgument("coils", "coil count S must be in 1.." + std::to_string(kMaxCoils) +
                                        ", got " + std::to_string(p.coils));
  }
  if (!p.coil_rigidity.empty() && static_cast<int>(p.coil_rigidity.size()) != p.coils) {
    return InvalidArgument("coil_rigidity",
                           "per-coil rigidity needs S = " + std::to_string(p.coils) +
                               " values, got " + std::to_string(p.coil_rigidity.size()));
  }
  const double ei = p.modulus * p.width * p.thickness * p.thickness * p.thickness / 12.0;  // eq. 2
  if (!PositiveFinite(ei)) {
    return InvalidArgument("modulus", "E·b·h³/12 is not a positive finite number (under/overflow)");
  }

  CoilSpringModel m;
  m.params_ = p;
  const int s = p.coils;
  m.ring_radius_.resize(s + 1);
  m.capacity_.assign(s + 1, 0.0);
  m.cum_capacity_.assign(s + 1, 0.0);
  m.rigidity_.assign(s + 1, 0.0);
  m.segment_compliance_.assign(s + 1, 0.0);
  m.cum_twist_.assign(s + 1, 0.0);
  m.ring_radius_[0] = p.core_radius;
  for (int i = 1; i <= s; ++i) {
    const double r_i = p.core_radius + i * p.thickness;  // eq. 1
    const double ei_i = p.coil_rigidity.empty() ? ei : p.coil_rigidity[i - 1];
    if (!PositiveFinite(ei_i)) {
      return InvalidArgument("coil_rigidity", "rigidity E·I of coil " + std::to_string(i) +
                                                  " must be finite and > 0, got " + Num(ei_i));
    }
    m.ring_radius_[i] = r_i;
    m.rigidity_[i] = ei_i;
    m.capacity_[i] = kTwoPi * r_i * p.max_force;  // eq. 3 with l_i = 2πR_i
    m.cum_capacity_[i] = m.cum_capacity_[i - 1] + m.capacity_[i];
    // φ_i = 2π·n_i = κ·M_i·l_i/(E·I_i) with l_i = 2πR_i (eq. 6–7): on segment i, dΦ/dM is this.
    m.segment_compliance_[i] = p.friction * kTwoPi * r_i / ei_i;
    m.cum_twist_[i] = m.cum_twist_[i - 1] + m.segment_compliance_[i] * m.capacity_[i];
  }
  if (!std::isfinite(m.cum_twist_[s]) || !std::isfinite(m.cum_capacity_[s])) {
    return InvalidArgument("coils", "the parameters overflow the twist or capacity range");
  }
  return m;
}

CoilState CoilSpringModel::MakeState() const {
  CoilState st;
  st.coil_torques.assign(params_.coils, 0.0);
  st.twist_turns.assign(params_.coils, 0.0);
  st.twist_angles.assign(params_.coils, 0.0);
  st.boundary_angles.assign(params_.coils + 1, 0.0);
  return st;
}

CoilState CoilSpringModel::Forward(double torque) const {
  CoilState st = MakeState();
  Forward(torque, st);
  return st;
}

// the coil-spring paper eq. 3–7. For |M| ≤ Q_S the cutoff layer P is the smallest p with Q_p ≥ |M|;
// coils below it carry their capacity C_i (eq. 3), coil P the rest M_P = |M| − Q_{P−1} (eq. 4) at
// the point force F_P = M_P/(2πR_P) (eq. 5), so its effective length l_P = M_P/F_P = 2πR_P (eq. 7).
// Turns n_i = κ·M_i·l_i/(2π·E·I_i) (eq. 6); twist φ_i = 2π·n_i; Θ_k = Σ_{k<i≤P} φ_i.
void CoilSpringModel::Forward(double torque, CoilState& out) const {
  const int s = params_.coils;
  if (static_cast<int>(out.boundary_angles.size()) != s + 1 ||
      static_cast<int>(out.coil_torques.size()) != s ||
      static_cast<int>(out.twist_turns.size()) != s ||
      static_cast<int>(out.twist_angles.size()) != s) {
    out = MakeState();  // a foreign or default state: size it once (allocates)
  }
  out.requested_torque = torque;
  out.invalid_input = !std::isfinite(torque);
  const double request = out.invalid_input ? 0.0 : torque;
  const double sign = request < 0 ? -1.0 : 1.0;
  double a = std::abs(request);
  out.overload = a > Capacity();
  if (out.overload) a = Capacity();  // clamp to capacity, P = S: never extrapolate
  out.torque = sign * a;
  if (a == 0) {
    out.cutoff = 0;
    out.total_twist = 0;
    out.boundary_angles[0] = 0;
    return;
  }
  const int p = FirstSegmentReaching(cum_capacity_, a);
  out.cutoff = p;
  for (int i = 1; i <= p; ++i) {
    const double m_i = i < p ? capacity_[i] : a - cum_capacity_[p - 1];
    const double l_i = kTwoPi * ring_radius_[i];
    const double n_i = params_.friction * m_i * l_i / (kTwoPi * rigidity_[i]);
    out.coil_torques[i - 1] = sign * m_i;
    out.twist_turns[i - 1] = sign * n_i;
    out.twist_angles[i - 1] = sign * kTwoPi * n_i;
  }
  out.boundary_angles[p] = 0;
  for (int k = p - 1; k >= 0; --k)
    out.boundary_angles[k] = out.boundary_angles[k + 1] + out.twist_angles[k];
  out.total_twist = out.boundary_angles[0];
}

// Φ(M) is continuous, increasing and piecewise linear with breakpoints (Q_p, Φcap_p) and slope
// κ·2π·R_p/(E·I_p) on segment p, so M(Φ) = Q_{p−1} + (Φ − Φcap_{p−1}) / slope_p on the segment
// found by binary search over Φcap.
CoilTorque CoilSpringModel::Inverse(double twist) const {
  CoilTorque r;
  if (!std::isfinite(twist)) {
    r.invalid_input = true;
    return r;
  }
  const double sign = twist < 0 ? -1.0 : 1.0;
  const double a = std::abs(twist);
  if (a == 0) {
    r.stiffness = 1.0 / segment_compliance_[1];
    return r;
  }
  if (a > TwistAtCapacity()) {
    r.overload = true;
    r.cutoff = params_.coils;
    r.torque = sign * Capacity();
    r.stiffness = 0;
    return r;
  }
  const int p = FirstSegmentReaching(cum_twist_, a);
  r.cutoff = p;
  r.torque = sign * (cum_capacity_[p - 1] + (a - cum_twist_[p - 1]) / segment_compliance_[p]);
  r.stiffness = 1.0 / segment_compliance_[p];
  return r;
}

double CoilSpringModel::TwistAt(double rho, const CoilState& st) const {
  const int p = st.cutoff;
  if (p == 0) return 0;
  rho = std::abs(rho);
  if (rho <= params_.core_radius) return st.boundary_angles[0];
  if (rho >= ring_radius_[p]) return 0;
  // Ring k spans [R_{k−1}, R_k]; linear interpolation of the boundary angles inside it.
  const int k = std::clamp(
      static_cast<int>(std::ceil((rho - params_.core_radius) / params_.thickness)), 1, p);
  const double t = std::clamp((rho - ring_radius_[k - 1]) / params_.thickness, 0.0, 1.0);
  return st.boundary_angles[k - 1] + t * (st.boundary_angles[k] - st.boundary_angles[k - 1]);
}

}  // namespace vsurg::tissue
