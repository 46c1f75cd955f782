// Simulation's four-handed training (guidance.h): the trainee's share of a shared tool, the trial's
// record of whose work it was, and the instructor's channel's haptic path. Haptic thread only.
#include <algorithm>
#include <cmath>

#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;
using haptics::ForceCommand;
using haptics::StylusSample;

// After the tool's step: keep the tissue's force on the tool for the instructor's answers, and,
// while the tool is shared, give the trainee their share of it and the coupling's pull, rendered
// by their station as a linear model (their own tip is not where the tool is).
void Simulation::ShareTool(const StylusSample& trainee, StylusStep& step) {
  ForceCommand& cmd = step.cmd;
  const bool touching = cmd.contact || cmd.grasping;
  tool_force_ = step.force;
  tool_slope_ = touching ? step.jacobian : Eigen::Matrix3d::Zero();  // not the surface ahead's
  tool_contact_ = touching;
  tool_proxy_ = cmd.proxy;
  trainee_x_ = trainee.position;
  cmd.guide_mode = static_cast<uint32_t>(guidance_.mode());
  cmd.guide_alpha = guidance_.alpha();
  if (!guidance_.shared()) return;
  step.force = guidance_.TraineeForce(step.force, trainee.position);
  step.jacobian = guidance_.TraineeSlope(tool_slope_);
  cmd.local = haptics::LocalModel{};  // linear, and the coupling to the instructor's hand
  cmd.local.pull_target = guidance_.instructor().position;
  cmd.local.pull_gain = guidance_.alpha();
  cmd.shared = true;
}

// The trial's record is the trainee's own work: their hand's path and their share of the tissue's
// force (not the coupling's pull, which is the guidance), the task's quantity at the tool; and
// how much of it was guided.
void Simulation::RecordSample(const StylusSample& trainee, const StylusStep& step,
                              const Vec3& out) {
  const double alpha = guidance_.alpha();
  const double force =
      alpha > 0 ? (1 - alpha) * std::min(tool_force_.norm(), scene_.haptics.limits.max_force)
                : out.norm();
  recorder_.Add(trial_time_, trainee.position, step.quantity, force, step.overload);
  recorder_.AddGuidance(trial_time_, alpha);
}

void Simulation::CountInstructorEnergy(const StylusSample& s) {
  if (instructor_has_x_) {
    const double w = instructor_force_.dot(s.position - instructor_x_);
    if (std::isfinite(w)) (w > 0 ? instructor_released_j_ : instructor_absorbed_j_) += std::abs(w);
  }
  instructor_x_ = s.position;
  instructor_has_x_ = true;
}

// The instructor's sample: their hand on the shared tool from now on, and their share of it as
// the trainee's last sample left the tool (guidance.h), through their own device limits.
ForceCommand Simulation::OnInstructorStylus(const StylusSample& s) {
  ForceCommand cmd;
  cmd.shared = true;
  cmd.guide_mode = static_cast<uint32_t>(guidance_.mode());
  cmd.guide_alpha = guidance_.alpha();
  cmd.score = live_score_;
  if (!instructor_safety_.AcceptInput(s, cmd.events)) {
    guidance_.DropInstructor();  // the tool is the trainee's again, ramped
    instructor_safety_.Disarm();
    instructor_force_.setZero();
    cmd.time = std::isfinite(s.time) ? s.time : instructor_time_;
    cmd.local.position0 = s.position.allFinite() ? s.position : Vec3::Zero();
    cmd.released_j = instructor_released_j_;
    cmd.absorbed_j = instructor_absorbed_j_;
    return cmd;
  }
  CountInstructorEnergy(s);
  const double step = instructor_has_time_ ? s.time - instructor_time_ : 0;
  const double dt = step > 0 && step < 0.1 ? step : 1e-3;
  instructor_time_ = s.time;
  instructor_has_time_ = true;
  guidance_.SetInstructor(s, trial_time_);
  Vec3 f = Vec3::Zero();
  if (guidance_.engaged()) {
    f = guidance_.InstructorForce(tool_force_, trainee_x_, s.position);
    cmd.local.jacobian = guidance_.InstructorSlope(tool_slope_);
    cmd.local.pull_target = trainee_x_;
    cmd.local.pull_gain = guidance_.InstructorGain();
  }
  const Vec3 out = instructor_safety_.Filter(f, dt, cmd.events);
  instructor_force_ = out;
  cmd.time = s.time;
  cmd.force = out;
  cmd.local.position0 = s.position;
  instructor_safety_.LimitLocalModel(cmd.local, out, cmd.events);
  cmd.contact = tool_contact_;
  cmd.proxy = tool_proxy_;
  cmd.released_j = instructor_released_j_;
  cmd.absorbed_j = instructor_absorbed_j_;
  return cmd;
}

}  // namespace vsurg::sim
