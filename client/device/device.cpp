#include "client/device/device.h"

#include <chrono>

namespace vsurg::client {

ReplayDevice::ReplayDevice(std::vector<haptics::StylusSample> samples, haptics::DeviceLimits limits,
                           Pace pace, const Clock* clock)
    : samples_(std::move(samples)),
      limits_(limits),
      pace_(pace),
      clock_(clock ? *clock : DefaultClock()) {
  forces_.reserve(samples_.size() + 1024);
}

haptics::StylusSample ReplayDevice::Read() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (samples_.empty()) return {};
  if (pace_ == Pace::kRealTime) {
    const double now = clock_.Now();
    if (start_s_ < 0) start_s_ = now;
    const double t = samples_.front().time + (now - start_s_);
    while (next_ < samples_.size() && samples_[next_].time <= t) ++next_;
    if (next_ == 0) return samples_.front();
    if (next_ == samples_.size()) return samples_.back();
    const haptics::StylusSample& a = samples_[next_ - 1];
    const haptics::StylusSample& b = samples_[next_];
    const double w = b.time > a.time ? (t - a.time) / (b.time - a.time) : 1.0;
    haptics::StylusSample s = a;
    s.time = t;
    s.position = a.position + w * (b.position - a.position);
    s.orientation = a.orientation.slerp(w, b.orientation);
    return s;
  }
  const size_t k = std::min(next_, samples_.size() - 1);
  if (next_ < samples_.size()) ++next_;
  return samples_[k];
}

void ReplayDevice::WriteForce(const Eigen::Vector3d& force) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (forces_.size() < forces_.capacity()) forces_.push_back(force);
}

std::vector<Eigen::Vector3d> ReplayDevice::forces() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return forces_;
}

size_t ReplayDevice::position() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_;
}

bool ReplayDevice::finished() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_ >= samples_.size();
}

Eigen::Vector3d ServoMailbox::Exchange(const haptics::StylusSample& sample) {
  std::lock_guard lock(mutex_);
  sample_ = sample;
  return force_;
}

haptics::StylusSample ServoMailbox::sample() const {
  std::lock_guard lock(mutex_);
  return sample_;
}

void ServoMailbox::set_force(const Eigen::Vector3d& force) {
  std::lock_guard lock(mutex_);
  force_ = force;
}

KeyboardMouseDevice::KeyboardMouseDevice(std::function<WindowInput()> input, Eigen::Vector3d start,
                                         Eigen::Vector3d twist_axis, double speed,
                                         haptics::DeviceLimits limits, const Clock* clock)
    : input_(std::move(input)),
      position_(start),
      axis_(twist_axis.normalized()),
      speed_(speed),
      limits_(limits),
      clock_(clock ? *clock : DefaultClock()) {}

haptics::StylusSample KeyboardMouseDevice::Read() {
  const double now = clock_.Now();
  const double dt = last_time_ < 0 ? 0.0 : std::min(now - last_time_, 0.05);
  last_time_ = now;
  const WindowInput in = input_ ? input_() : WindowInput{};
  const Eigen::Vector3d velocity(double(in.right) - double(in.left),
                                 double(in.forward) - double(in.back),
                                 double(in.up) - double(in.down));
  position_ += speed_ * dt * velocity;
  position_ = position_.cwiseMax(limits_.workspace_min).cwiseMin(limits_.workspace_max);
  haptics::StylusSample s;
  s.time = now;
  s.position = position_;
  s.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(in.twist_rad, axis_));
  s.buttons = (in.grasp ? haptics::kButtonGrasp : 0u) | (in.mark ? haptics::kButtonMark : 0u);
  return s;
}

void KeyboardMouseDevice::WriteForce(const Eigen::Vector3d& force) {
  std::lock_guard lock(mutex_);
  force_ = force;
}

Eigen::Vector3d KeyboardMouseDevice::last_force() const {
  std::lock_guard lock(mutex_);
  return force_;
}

}  // namespace vsurg::client
