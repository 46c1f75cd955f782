#include "client/device/virtual_hand.h"

#include <algorithm>
#include <cmath>

namespace vsurg::client {

HandImpedance RelaxedGrip() {
  return {0.55, 6.5, 135};
}
HandImpedance TensedGrip() {
  return {0.55, 13, 540};
}

Expected<HandImpedance> GripByName(const std::string& name) {
  if (name == "relaxed") return RelaxedGrip();
  if (name == "tensed") return TensedGrip();
  return InvalidArgument("--grip", "'" + name + "' is not relaxed or tensed");
}

Expected<std::unique_ptr<VirtualHandDevice>> VirtualHandDevice::Create(
    std::vector<haptics::StylusSample> plan, HandImpedance hand, DeviceModel device, double rate_hz,
    int substeps) {
  if (plan.empty()) return InvalidArgument("plan", "the virtual hand needs a plan");
  for (const auto& s : plan)
    if (!s.position.allFinite() || !std::isfinite(s.time))
      return InvalidArgument("plan", "the plan has a non-finite sample");
  if (!(hand.mass > 0 && hand.damping >= 0 && hand.stiffness > 0))
    return InvalidArgument("hand", "mass and stiffness must be > 0, damping ≥ 0");
  if (!(device.mass >= 0 && device.friction >= 0 && device.resolution >= 0))
    return InvalidArgument("device", "mass, friction and resolution must be ≥ 0");
  if (!(rate_hz >= 100 && rate_hz <= 20000) || substeps < 1 || substeps > 1000)
    return InvalidArgument("rate_hz", "rate within 100..20000 Hz, 1..1000 substeps");
  return std::unique_ptr<VirtualHandDevice>(
      new VirtualHandDevice(std::move(plan), hand, device, rate_hz, substeps));
}

VirtualHandDevice::VirtualHandDevice(std::vector<haptics::StylusSample> plan, HandImpedance hand,
                                     DeviceModel device, double rate_hz, int substeps)
    : plan_(std::move(plan)), hand_(hand), device_(device), rate_hz_(rate_hz), substeps_(substeps) {
  x_ = plan_.front().position;
  trace_.reserve(static_cast<size_t>((plan_duration() + 30) * rate_hz_));
}

double VirtualHandDevice::plan_duration() const {
  return plan_.back().time - plan_.front().time;
}

haptics::StylusSample VirtualHandDevice::PlanAt(double t) const {
  const double t0 = plan_.front().time;
  const double want = t0 + t;
  auto it = std::upper_bound(plan_.begin(), plan_.end(), want,
                             [](double v, const haptics::StylusSample& s) { return v < s.time; });
  if (it == plan_.begin()) return plan_.front();
  if (it == plan_.end()) return plan_.back();
  const haptics::StylusSample& a = *(it - 1);
  const haptics::StylusSample& b = *it;
  const double w = b.time > a.time ? (want - a.time) / (b.time - a.time) : 1.0;
  haptics::StylusSample s = a;
  s.position = a.position + w * (b.position - a.position);
  s.orientation = a.orientation.slerp(w, b.orientation);
  return s;
}

haptics::StylusSample VirtualHandDevice::Read() {
  std::lock_guard<std::mutex> lock(mutex_);
  const double period = 1.0 / rate_hz_;
  if (started_) {
    // One servo period under the force held since the last write.
    const double h = period / substeps_;
    const double m = hand_.mass + device_.mass;
    for (int k = 0; k < substeps_; ++k) {
      const double t = t_ + k * h;
      const Eigen::Vector3d xp = PlanAt(t).position + offset_;
      const Eigen::Vector3d vp = (PlanAt(t + 1e-3).position - PlanAt(t - 1e-3).position) / 2e-3;
      Eigen::Vector3d f = hand_.stiffness * (xp - x_) + hand_.damping * (vp - v_) + held_;
      for (int a = 0; a < 3; ++a) f[a] -= device_.friction * std::tanh(v_[a] / 0.002);
      v_ += (h / m) * f;
      x_ += h * v_;
    }
    t_ += period;
  }
  started_ = true;
  haptics::StylusSample s = PlanAt(t_);
  s.time = t_;
  s.position = x_;
  if (device_.resolution > 0)
    for (int a = 0; a < 3; ++a)
      s.position[a] = std::round(x_[a] / device_.resolution) * device_.resolution;
  if (trace_.size() < trace_.capacity())
    trace_.push_back({t_, x_, PlanAt(t_).position + offset_, held_, s.buttons});
  return s;
}

void VirtualHandDevice::WriteForce(const Eigen::Vector3d& force) {
  std::lock_guard<std::mutex> lock(mutex_);
  Eigen::Vector3d f = force.allFinite() ? force : Eigen::Vector3d::Zero();
  const double n = f.norm();
  if (n > device_.limits.max_force) f *= device_.limits.max_force / n;  // the motors saturate
  held_ = f;
  if (!trace_.empty()) trace_.back().force = f;
}

void VirtualHandDevice::Correct(const Eigen::Vector3d& offset) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (offset.allFinite()) offset_ = offset;
}

bool VirtualHandDevice::finished() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return t_ >= plan_duration();
}

size_t VirtualHandDevice::cycles() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return trace_.size();
}

std::vector<HandSample> VirtualHandDevice::trace() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return trace_;
}

}  // namespace vsurg::client
