// Device safety: every force leaves through here (DESIGN.md "Haptic interaction").
//
//   1. input check: a non-finite or out-of-workspace sample gives zero force and an event;
//   2. start-up gating: nothing is output until the requested force has stayed below
//      gate_force for gate_cycles samples (or gate_cycles ms, when samples come sparser) (no kick
//      when a session starts with the tip inside tissue), then the output is ramped in over
//      ramp_time;
//   3. magnitude clamp to max_force; 4. rate limit |ΔF| ≤ max_force_rate·dt (the output's
//      magnitude is ≤ max_force exactly, in the double arithmetic a check of it uses);
//   5. local-model stiffness clamped to max_stiffness (largest |eigenvalue| of the symmetric part).
//
// Presets: Touch-class 3.3 N peak, 400 N/m; Omni-class 3.3 N, 700 N/m (OpenHaptics figures).
// Threads: one filter per haptic loop; no allocation.
#pragma once

#include <cstdint>

#include "common/core/expected.h"
#include "common/haptics/types.h"

namespace vsurg::haptics {

struct DeviceLimits {
  double max_force = 3.3;                       // N
  double max_force_rate = 1000.0;               // N/s
  double max_stiffness = 400.0;                 // N/m
  Vec3 workspace_min = Vec3(-0.5, -0.5, -0.5);  // m, scene frame
  Vec3 workspace_max = Vec3(0.5, 0.5, 0.5);
};

DeviceLimits TouchLimits();
DeviceLimits OmniLimits();
// "touch" or "omni".
Expected<DeviceLimits> DeviceLimitsByName(const std::string& name);

struct GateParams {
  double gate_force = 0.2;  // N: the request must stay below this ...
  int gate_cycles = 50;     // ... for this many samples before output starts
  double ramp_time = 0.5;   // s: then the output ramps from 0 to 1 over this time
};

class SafetyFilter {
 public:
  static Expected<SafetyFilter> Create(const DeviceLimits& limits, const GateParams& gate = {});

  // Step 1: false (and events set) when the sample must give zero force.
  bool AcceptInput(const StylusSample& sample, uint32_t& events) const;
  // Steps 2–4 for a request at a sample dt seconds after the previous one (dt ≤ 0 or non-finite:
  // 1 ms assumed). Returns the force to output.
  Vec3 Filter(const Vec3& requested, double dt, uint32_t& events);
  // Step 5, and scales the local model consistently with the output: its force is the output,
  // and its stiffness is scaled by the start-up gate and ramp as the force was (zero while
  // gated), so that a station extrapolating it between updates never renders a force the gate
  // held back (a session started, or re-placed after a node's loss, with the tip in tissue).
  void LimitLocalModel(LocalModel& local, const Vec3& output, uint32_t& events) const;
  // Output zero now and go back to the start-up gate (the next force is gated and ramped).
  void Disarm();

  const DeviceLimits& limits() const { return limits_; }
  bool armed() const { return armed_; }
  // The filter's state (common/core/state_archive.h), not its limits.
  template <class A>
  void Persist(A& a) {
    a(last_, quiet_, quiet_time_, armed_, armed_time_, ramp_);
  }

 private:
  SafetyFilter(const DeviceLimits& l, const GateParams& g) : limits_(l), gate_(g) {}
  DeviceLimits limits_;
  GateParams gate_;
  Vec3 last_ = Vec3::Zero();
  int quiet_ = 0;
  double quiet_time_ = 0;  // s the request has been quiet (see Filter)
  bool armed_ = false;
  double armed_time_ = 0;  // s since arming
  double ramp_ = 0;        // the last Filter's gate-and-ramp factor, 0..1
};

}  // namespace vsurg::haptics
