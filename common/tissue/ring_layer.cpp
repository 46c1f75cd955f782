#include "common/tissue/ring_layer.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace vsurg::tissue {

using geometry::Vec3;

Expected<RingLayerModel> RingLayerModel::Create(const std::vector<Vec3>& rest,
                                                const std::vector<double>& distance,
                                                const std::vector<double>& masses,
                                                const Vec3& press_direction,
                                                const RingLayerParams& p) {
  auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  auto non_negative = [](double x) { return std::isfinite(x) && x >= 0; };
  if (!positive(p.ring_spacing))
    return InvalidArgument("ring_spacing", "ring spacing must be > 0 m");
  if (p.rings < 1 || p.rings > 10000)
    return InvalidArgument("rings", "ring count must be in 1..10000");
  if (!positive(p.chain_stiffness))
    return InvalidArgument("chain_stiffness", "chain stiffness must be > 0 N/m");
  if (!non_negative(p.chain_damping))
    return InvalidArgument("chain_damping", "chain damping must be ≥ 0 N·s/m");
  if (!non_negative(p.tether_stiffness))
    return InvalidArgument("tether_stiffness", "tether stiffness must be ≥ 0 N/m");
  if (!press_direction.allFinite() || !(press_direction.norm() > 0)) {
    return InvalidArgument("press_direction", "press direction must be a finite non-zero vector");
  }
  if (distance.size() != rest.size() || masses.size() != rest.size()) {
    return InvalidArgument("mesh", "need one distance and one mass per vertex");
  }
  RingLayerModel m;
  m.params_ = p;
  m.dir_ = press_direction.normalized();
  const int k_rings = p.rings;
  m.mass_.assign(k_rings, 0.0);
  m.tether_.assign(k_rings, 0.0);
  m.u_.assign(k_rings + 1, 0.0);  // u_K = 0 stays
  m.v_.assign(k_rings + 1, 0.0);
  m.rest_ = rest;
  m.deformed_ = rest;
  std::vector<int> count(k_rings, 0);
  for (size_t i = 0; i < rest.size(); ++i) {
    if (!(masses[i] > 0) || !std::isfinite(masses[i])) {
      return InvalidArgument("masses",
                             "vertex " + std::to_string(i) + " mass must be finite and > 0 kg");
    }
    if (std::isnan(distance[i]) || distance[i] < 0) {
      return InvalidArgument("distance", "vertex " + std::to_string(i) + " distance must be ≥ 0 m");
    }
    const double s = distance[i] / p.ring_spacing;
    if (!(s < k_rings)) continue;  // at or beyond ring K: fixed
    const int nearest = static_cast<int>(std::lround(s));
    if (nearest < k_rings) {
      m.mass_[nearest] += masses[i];
      ++count[nearest];
    }
    m.vertex_.push_back(static_cast<int>(i));
    m.ring_.push_back(static_cast<int>(s));
    m.frac_.push_back(s - std::floor(s));
  }
  for (int k = 0; k < k_rings; ++k) {
    if (count[k] == 0) {
      return InvalidArgument(
          "ring_spacing",
          "ring " + std::to_string(k) +
              " holds no vertex: make the ring spacing larger than the mesh spacing");
    }
    m.tether_[k] = p.tether_stiffness * count[k];
  }
  for (auto* v : {&m.sub_, &m.diag_, &m.sup_, &m.rhs_}) v->assign(k_rings, 0.0);
  m.u_prev_.assign(k_rings + 1, 0.0);
  return m;
}

void RingLayerModel::SetContactDisplacement(double u) {
  if (!std::isfinite(u)) return;
  drive_by_displacement_ = true;
  drive_ = u;
}

void RingLayerModel::SetContactForce(double f) {
  if (!std::isfinite(f)) return;
  drive_by_displacement_ = false;
  drive_ = f;
}

// Backward Euler in the new displacements u¹ (v¹ = (u¹ − u⁰)/h), with g = k_c + c_c/h:
//   (m_k/h² + t_k) u¹_k − g Δu¹_k = m_k (u⁰_k + h v⁰_k)/h² − (c_c/h) Δu⁰_k + f_k,
// Δ the chain Laplacian (ring 0 has one neighbour, ring K is fixed at zero). h = 0: statics,
// t_k u_k − k_c Δu_k = f_k. A driven ring 0 moves to the right-hand side.
void RingLayerModel::Solve(double h) {
  const int k_rings = params_.rings;
  const bool dynamic = h > 0;
  const double g = params_.chain_stiffness + (dynamic ? params_.chain_damping / h : 0.0);
  const double cdh = dynamic ? params_.chain_damping / h : 0.0;
  const int first = drive_by_displacement_ ? 1 : 0;
  std::copy(u_.begin(), u_.end(), u_prev_.begin());
  const std::vector<double>& u0 = u_prev_;
  auto lap0 = [&](int k) {
    const double left = k > 0 ? u0[k - 1] - u0[k] : 0.0;
    return left + (u0[k + 1] - u0[k]);
  };
  for (int k = first; k < k_rings; ++k) {
    const double inertia = dynamic ? mass_[k] / (h * h) : 0.0;
    const int neighbours = k > 0 ? 2 : 1;
    diag_[k] = inertia + tether_[k] + g * neighbours;
    sub_[k] = k > first ? -g : 0.0;
    sup_[k] = k + 1 < k_rings ? -g : 0.0;
    rhs_[k] = dynamic ? mass_[k] * (u0[k] + h * v_[k]) / (h * h) - cdh * lap0(k) : 0.0;
    if (k == 0 && !drive_by_displacement_) rhs_[k] += drive_;
    if (k == 1 && drive_by_displacement_) rhs_[k] += g * drive_;
  }
  // Thomas algorithm.
  for (int k = first + 1; k < k_rings; ++k) {
    const double w = sub_[k] / diag_[k - 1];
    diag_[k] -= w * sup_[k - 1];
    rhs_[k] -= w * rhs_[k - 1];
  }
  if (drive_by_displacement_) u_[0] = drive_;
  for (int k = k_rings - 1; k >= first; --k) {
    u_[k] = (rhs_[k] - (k + 1 < k_rings ? sup_[k] * u_[k + 1] : 0.0)) / diag_[k];
  }
  u_[k_rings] = 0;
  for (int k = 0; k < k_rings; ++k) {
    const double v1 = dynamic ? (u_[k] - u0[k]) / h : 0.0;
    if (k == 0) {
      // The tool's force on ring 0: m_0 a_0 minus the tissue's internal force on it.
      const double internal = params_.chain_stiffness * (u_[1] - u_[0]) +
                              (dynamic ? params_.chain_damping * ((u_[1] - u0[1]) / h - v1) : 0.0) -
                              tether_[0] * u_[0];
      const double inertia = dynamic ? mass_[0] * (v1 - v_[0]) / h : 0.0;
      contact_force_ = drive_by_displacement_ ? inertia - internal : drive_;
    }
    v_[k] = v1;
  }
}

bool RingLayerModel::Step(double dt) {
  if (!(std::isfinite(dt) && dt > 0)) return false;
  Solve(dt);
  return true;
}

void RingLayerModel::SolveStatic() {
  Solve(0.0);
}

int RingLayerModel::Apply() {
  for (size_t n = 0; n < vertex_.size(); ++n) {
    const int k = ring_[n];
    const double u = u_[k] + frac_[n] * (u_[k + 1] - u_[k]);
    deformed_[vertex_[n]] = rest_[vertex_[n]] + u * dir_;
  }
  return static_cast<int>(vertex_.size());
}

double RingLayerModel::PotentialEnergy() const {
  double e = 0;
  for (int k = 0; k < params_.rings; ++k) {
    const double s = u_[k] - u_[k + 1];
    e += 0.5 * params_.chain_stiffness * s * s + 0.5 * tether_[k] * u_[k] * u_[k];
  }
  return e;
}

double RingLayerModel::KineticEnergy() const {
  double e = 0;
  for (int k = 0; k < params_.rings; ++k) e += 0.5 * mass_[k] * v_[k] * v_[k];
  return e;
}

}  // namespace vsurg::tissue
