#include "client/device/device.h"

namespace vsurg::client {

ReplayDevice::ReplayDevice(std::vector<haptics::StylusSample> samples, haptics::DeviceLimits limits)
    : samples_(std::move(samples)), limits_(limits) {
  forces_.reserve(samples_.size() + 1024);
}

haptics::StylusSample ReplayDevice::Read() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (samples_.empty()) return {};
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

}  // namespace vsurg::client
