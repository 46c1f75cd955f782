// Shared control of a session's tool (guidance.h).
#include "common/sim/guidance.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace vsurg::sim {

using haptics::StylusSample;
using haptics::Vec3;

const char* GuideModeName(GuideMode mode) {
  switch (mode) {
    case GuideMode::kNone:
      return "none";
    case GuideMode::kObserve:
      return "observe";
    case GuideMode::kGuide:
      return "guide";
  }
  return "none";
}

Expected<GuideMode> ParseGuideMode(std::string_view name) {
  for (GuideMode m : {GuideMode::kNone, GuideMode::kObserve, GuideMode::kGuide})
    if (name == GuideModeName(m)) return m;
  return Error{ErrorCode::kInvalidArgument,
               "mode must be none, observe or guide, not '" + std::string(name) + "'", "mode"};
}

Status CheckGuideRequest(const GuideRequest& r) {
  if (r.mode != GuideMode::kNone && r.mode != GuideMode::kObserve && r.mode != GuideMode::kGuide)
    return Error{ErrorCode::kInvalidArgument, "unknown guidance mode", "mode"};
  if (!(r.alpha >= 0 && r.alpha <= 1))
    return Error{ErrorCode::kInvalidArgument, "the dominance alpha must be within [0, 1]", "alpha"};
  if (r.mode != GuideMode::kGuide && r.alpha != 0)
    return Error{ErrorCode::kInvalidArgument, "alpha is the guide mode's; observe shares nothing",
                 "alpha"};
  return Status::Ok();
}

// One word: the mode in the high 32 bits, α as a float's bits in the low 32.
uint64_t Guidance::Pack(const GuideRequest& r) {
  const float a = static_cast<float>(std::clamp(r.alpha, 0.0, 1.0));
  return (static_cast<uint64_t>(r.mode) << 32) | std::bit_cast<uint32_t>(a);
}

GuideRequest Guidance::Unpack(uint64_t word) {
  GuideRequest r;
  r.mode = static_cast<GuideMode>(word >> 32);
  r.alpha = std::bit_cast<float>(static_cast<uint32_t>(word & 0xffffffffu));
  return r;
}

void Guidance::Request(const GuideRequest& r) {
  request_.store(Pack(r), std::memory_order_release);
}

GuideRequest Guidance::requested() const {
  return Unpack(request_.load(std::memory_order_acquire));
}

void Guidance::Advance(double now) {
  const double dt = now - now_;
  now_ = now;
  const GuideRequest r = requested();
  mode_ = r.mode;
  const bool present = has_instructor_ && now - instructor_at_ <= kStaleS;
  const double alpha_to = present && r.mode == GuideMode::kGuide ? r.alpha : 0.0;
  const double follow_to = present && r.mode == GuideMode::kObserve ? 1.0 : 0.0;
  const double step = kRampPerS * std::clamp(dt, 0.0, 0.1);
  alpha_ += std::clamp(alpha_to - alpha_, -step, step);
  follow_ += std::clamp(follow_to - follow_, -step, step);
}

void Guidance::SetInstructor(const StylusSample& s, double now) {
  instructor_ = s;
  instructor_at_ = now;
  has_instructor_ = true;
}

StylusSample Guidance::Tool(const StylusSample& t) const {
  if (!(alpha_ > 0)) return t;
  StylusSample v = t;
  v.position = (1 - alpha_) * t.position + alpha_ * instructor_.position;
  v.orientation = t.orientation.normalized().slerp(alpha_, instructor_.orientation.normalized());
  v.buttons = alpha_ >= 0.5 ? instructor_.buttons : t.buttons;
  return v;
}

Vec3 Guidance::TraineeForce(const Vec3& tissue, const Vec3& x_t) const {
  return (1 - alpha_) * tissue + alpha_ * haptics::CouplingPull(instructor_.position - x_t);
}

Vec3 Guidance::InstructorForce(const Vec3& tissue, const Vec3& x_t, const Vec3& x_i) const {
  return InstructorGain() * (tissue + haptics::CouplingPull(x_t - x_i));
}

Eigen::Matrix3d Guidance::TraineeSlope(const Eigen::Matrix3d& tissue) const {
  return (1 - alpha_) * (1 - alpha_) * tissue;
}

Eigen::Matrix3d Guidance::InstructorSlope(const Eigen::Matrix3d& tissue) const {
  return InstructorGain() * alpha_ * tissue;
}

}  // namespace vsurg::sim
