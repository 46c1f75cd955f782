#include "common/haptics/safety.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace vsurg::haptics {

DeviceLimits TouchLimits() {
  DeviceLimits l;
  l.max_force = 3.3;
  l.max_stiffness = 400.0;
  return l;
}

DeviceLimits OmniLimits() {
  DeviceLimits l;
  l.max_force = 3.3;
  l.max_stiffness = 700.0;
  return l;
}

Expected<DeviceLimits> DeviceLimitsByName(const std::string& name) {
  if (name == "touch") return TouchLimits();
  if (name == "omni") return OmniLimits();
  return InvalidArgument("device", "unknown device '" + name + "' (touch, omni)");
}

Expected<SafetyFilter> SafetyFilter::Create(const DeviceLimits& l, const GateParams& g) {
  auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  if (!positive(l.max_force)) return InvalidArgument("max_force", "device max force must be > 0 N");
  if (!positive(l.max_force_rate))
    return InvalidArgument("max_force_rate", "device max force rate must be > 0 N/s");
  if (!positive(l.max_stiffness))
    return InvalidArgument("max_stiffness", "device max stiffness must be > 0 N/m");
  if (!l.workspace_min.allFinite() || !l.workspace_max.allFinite() ||
      !(l.workspace_min.array() < l.workspace_max.array()).all()) {
    return InvalidArgument("workspace", "device workspace must be a finite box with min < max");
  }
  if (!(g.gate_force >= 0) || g.gate_cycles < 0 || !(g.ramp_time >= 0)) {
    return InvalidArgument("gate", "gate force, cycles and ramp time must be ≥ 0");
  }
  return SafetyFilter(l, g);
}

bool SafetyFilter::AcceptInput(const StylusSample& s, uint32_t& events) const {
  if (!s.position.allFinite() || !s.orientation.coeffs().allFinite() || !std::isfinite(s.time)) {
    events |= kEventNonFiniteInput;
    return false;
  }
  if ((s.position.array() < limits_.workspace_min.array()).any() ||
      (s.position.array() > limits_.workspace_max.array()).any()) {
    events |= kEventOutOfWorkspace;
    return false;
  }
  return true;
}

Vec3 SafetyFilter::Filter(const Vec3& requested_in, double dt, uint32_t& events) {
  if (!(std::isfinite(dt) && dt > 0)) dt = 1e-3;
  Vec3 requested = requested_in;
  if (!requested.allFinite()) {
    events |= kEventNonFiniteInput;
    requested.setZero();
  }
  // Start-up gate, then ramp-in.
  double ramp = 1.0;
  if (!armed_) {
    // Quiet for gate_cycles samples, or as long as that many 1 ms cycles take: a station behind
    // the perceptual deadband sends a sample only every few tens of milliseconds.
    const bool quiet = requested.norm() < gate_.gate_force;
    quiet_ = quiet ? quiet_ + 1 : 0;
    quiet_time_ = quiet ? quiet_time_ + dt : 0.0;
    if (quiet_ >= gate_.gate_cycles || quiet_time_ >= 1e-3 * gate_.gate_cycles) {
      armed_ = true;
      armed_time_ = 0;
    } else {
      events |= kEventGated;
      requested.setZero();
    }
  }
  if (armed_) {
    armed_time_ += dt;
    ramp = gate_.ramp_time > 0 ? std::min(1.0, armed_time_ / gate_.ramp_time) : 1.0;
  }
  Vec3 out = ramp * requested;
  const double mag = out.norm();
  if (mag > limits_.max_force) {
    out *= limits_.max_force / mag;
    events |= kEventForceClamped;
  }
  const Vec3 step = out - last_;
  const double max_step = limits_.max_force_rate * dt;
  if (step.norm() > max_step) {
    out = last_ + step * (max_step / step.norm());
    events |= kEventRateLimited;
  }
  // Scaling by max/|out| can leave |out| an ulp above max (3.3000000000000003 N): scale below it
  // until the norm, as computed by anyone who checks it, is within the limit.
  for (double n = out.norm(); n > limits_.max_force; n = out.norm())
    out *= std::nextafter(limits_.max_force / n, 0.0);
  ramp_ = armed_ ? ramp : 0.0;
  last_ = out;
  return out;
}

void SafetyFilter::LimitLocalModel(LocalModel& local, const Vec3& output, uint32_t& events) const {
  Eigen::Matrix3d& j = local.jacobian;
  if (!j.allFinite() || !local.position0.allFinite()) {
    j.setZero();
    events |= kEventNonFiniteInput;
  }
  const Eigen::Matrix3d sym = 0.5 * (j + j.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(sym, Eigen::EigenvaluesOnly);
  const double k = eig.eigenvalues().cwiseAbs().maxCoeff();
  if (k > limits_.max_stiffness) {
    j *= limits_.max_stiffness / k;
    events |= kEventStiffnessClamped;
  }
  if (!local.dforce_dtwist.allFinite() || !local.axis.allFinite() ||
      !local.orientation0.coeffs().allFinite() || !local.normal.allFinite()) {
    local.kind = LocalModel::Kind::kLinear;
    local.dforce_dtwist.setZero();
    events |= kEventNonFiniteInput;
  }
  if (local.has_twist_model && (!local.force_per_torque.allFinite() || !local.arm.allFinite() ||
                                !std::isfinite(local.torque0) ||
                                !std::all_of(local.torque_steps.begin(), local.torque_steps.end(),
                                             [](double t) { return std::isfinite(t); }))) {
    local.has_twist_model = false;  // the tangent alone (g), which was checked above
    events |= kEventNonFiniteInput;
  }
  if (!std::isfinite(local.tissue_stiffness) || !std::isfinite(local.tissue_damping) ||
      !std::isfinite(local.tissue_elastic0) || !(local.tissue_stiffness >= 0) ||
      !(local.tissue_damping >= 0)) {
    local.tissue_stiffness = local.tissue_damping = local.tissue_elastic0 = 0;
    events |= kEventNonFiniteInput;
  }
  if (!std::isfinite(local.contact_damping) || !(local.contact_damping >= 0)) {
    local.contact_damping = 0;
    events |= kEventNonFiniteInput;
  }
  if (!local.pull_target.allFinite() || !std::isfinite(local.pull_gain) ||
      !(local.pull_gain >= 0)) {
    local.pull_target.setZero();
    local.pull_gain = 0;
    events |= kEventNonFiniteInput;
  }
  local.pull_gain = std::min(local.pull_gain, 1.0) * ramp_;
  j *= ramp_;  // gated: no stiffness either; ramping: as much as the force
  local.dforce_dtwist *= ramp_;
  local.force_per_torque *= ramp_;  // the exact model's tissue part; its hold part is J's
  local.tissue_stiffness *= ramp_, local.tissue_damping *= ramp_, local.tissue_elastic0 *= ramp_;
  local.contact_damping *= ramp_;
  local.force0 = output;  // the extrapolation starts from what the device actually outputs
}

void SafetyFilter::Disarm() {
  armed_ = false;
  ramp_ = 0;
  quiet_ = 0;
  quiet_time_ = 0;
  last_.setZero();
}

}  // namespace vsurg::haptics
