// Four-handed training: one session's tool shared by its trainee and an instructor (docs/DESIGN.md
// "Shared control").
//
// The instructor's station joins a live session on a channel of its own; its samples reach the
// session's haptic thread (the trainee's lane) and set the instructor's hand x_i, the trainee's
// set x_t. Two weights, ramped on the haptic thread towards what the instructor asked for: the
// dominance α ∈ [0, 1] (Nudehi, Mukherjee & Ghodoussi, IEEE TCST 2005: 0 the trainee alone, 1 the
// instructor alone) and the follow weight f ∈ [0, 1] (1 in observe, 0 in guide). The tool the
// tissue meets is
//
//   x_v = (1 − α)·x_t + α·x_i, its orientation the slerp by α, its buttons the dominant hand's,
//
// and with F the tissue's force on it and k_c the hands' coupling (N/m):
//
//   trainee     F_t = (1 − α)·F + α·c(x_i − x_t)
//   instructor  F_i =      α·F + α·c(x_t − x_i) + f·(1 − α)·(F + c(x_t − x_i)),
//
// c(d) = k_c·d up to a pull of kMaxPull (a hand far from the tool is led, not yanked).
//
// observe (α = 0, f = 1): the trainee feels F alone, as without an instructor; the instructor's
// device is led along the trainee's tool by the coupling and feels the tissue as the trainee does
// (haptic playback). guide (f = 0): the tissue's force shared in proportion and one spring α·k_c
// between the hands, equal and opposite; α = 1 is "take over" (the trainee's hand led along the
// instructor's tool), α back to 0 "hand back".
//
// Passivity without delay: the shared part does work F·((1 − α)·dx_t + α·dx_i) = F·dx_v on the
// hands, exactly the tissue's on the tool, so it is as passive as the tissue; the coupling is a
// conservative spring (energy ½·α·k_c·|x_i − x_t|²) while α holds. A change of α changes that
// energy by ½·Δα·k_c·|x_i − x_t|²: α and f move at most kRampPerS per second (a take-over in
// 0.5 s), so no mode change is a step in force. The playback term is a source on the
// instructor's port driven by the trainee's hand, by design; its energy is counted on the
// instructor's port like the rest (the station's passivity control bounds what it is given).
//
// The instructor's hand counts only while its samples are fresh: older than kStaleS on the
// trainee's clock (a lost link, a station gone), the request falls back to the trainee alone and
// α ramps down; the trainee is never held by a hand that no longer answers.
//
// Threads: Request from any thread (one atomic word); everything else on the haptic thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/core/expected.h"
#include "common/haptics/types.h"

namespace vsurg::sim {

enum class GuideMode : uint32_t { kNone = 0, kObserve = 1, kGuide = 2 };  // wire values: keep
const char* GuideModeName(GuideMode mode);                                // "none", ...
Expected<GuideMode> ParseGuideMode(std::string_view name);

struct GuideRequest {
  GuideMode mode = GuideMode::kNone;
  double alpha = 0;  // guide only, within [0, 1]
};
// kInvalidArgument for an α outside [0, 1] or not finite, or one given with another mode.
Status CheckGuideRequest(const GuideRequest& r);

class Guidance {
 public:
  static constexpr double kCouplingStiffness = haptics::kCouplingStiffness;  // N/m, k_c
  static constexpr double kMaxPull = haptics::kMaxPull;  // N, the coupling's pull at most
  static constexpr double kRampPerS = 2.0;               // α and f, per second
  static constexpr double kStaleS = 0.25;                // s of the trainee's clock

  // Any thread: what the instructor asked for (kNone when they left).
  void Request(const GuideRequest& r);
  GuideRequest requested() const;

  // Haptic thread, once per trainee sample at trial time `now` (s, the trial clock): ramps α and
  // f towards the request by the clock's advance since the call before (the trainee alone while
  // the instructor's sample is stale).
  void Advance(double now);
  // Haptic thread: the instructor's newest accepted sample, at trial time `now`.
  void SetInstructor(const haptics::StylusSample& s, double now);
  void DropInstructor() { has_instructor_ = false; }

  // The tool is not the trainee's alone (α > 0): its answer is the shared one.
  bool shared() const { return alpha_ > 0; }
  // The instructor is present and weighs in (α or f above zero): their answer is not zero.
  bool engaged() const { return has_instructor_ && (alpha_ > 0 || follow_ > 0); }
  double alpha() const { return alpha_; }
  double follow() const { return follow_; }
  GuideMode mode() const { return mode_; }
  const haptics::StylusSample& instructor() const { return instructor_; }

  // The tool the tissue meets for the trainee's sample `t` (t itself while α = 0).
  haptics::StylusSample Tool(const haptics::StylusSample& t) const;
  // The hands' forces for the tissue's force F on the tool (formulas above), and what the
  // stations' local models need: the tissue's share of the slope, ∂F_t/∂x_t = (1 − α)²·J and
  // ∂F_i/∂x_i = (α + f(1 − α))·α·J with J the tissue's ∂F/∂x at the tool, and the coupling, which
  // a station evaluates itself (haptics::LocalModel::pull_target, its gain: α for the trainee,
  // α + f(1 − α) for the instructor).
  haptics::Vec3 TraineeForce(const haptics::Vec3& tissue, const haptics::Vec3& x_t) const;
  haptics::Vec3 InstructorForce(const haptics::Vec3& tissue, const haptics::Vec3& x_t,
                                const haptics::Vec3& x_i) const;
  Eigen::Matrix3d TraineeSlope(const Eigen::Matrix3d& tissue) const;
  Eigen::Matrix3d InstructorSlope(const Eigen::Matrix3d& tissue) const;
  double InstructorGain() const { return alpha_ + follow_ * (1 - alpha_); }

 private:
  static uint64_t Pack(const GuideRequest& r);
  static GuideRequest Unpack(uint64_t word);

  std::atomic<uint64_t> request_{0};
  double alpha_ = 0, follow_ = 0;
  GuideMode mode_ = GuideMode::kNone;  // the request as last applied
  haptics::StylusSample instructor_;
  double instructor_at_ = 0;  // trial time of the instructor's newest sample
  double now_ = 0;            // trial time of the last Advance
  bool has_instructor_ = false;
};

}  // namespace vsurg::sim
