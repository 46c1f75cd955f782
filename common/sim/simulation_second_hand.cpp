// Simulation's second hand (simulation.h OnSecondHandStylus): a cut scene's grasper, driven by the
// station's second device on a channel of its own. Its jaws close on the patch and hold the
// particle under them toward themselves (the cut room's spring, inside the patch's implicit
// step); the hand feels the patch's pull. Both hands' samples run on the session's one haptic
// thread, so the state here needs no lock; the trial's clock is the first hand's.
#include <algorithm>
#include <cmath>

#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;
using haptics::ForceCommand;
using haptics::StylusSample;

ForceCommand Simulation::OnSecondHandStylus(const StylusSample& s) {
  ForceCommand cmd;
  cmd.score = live_score_;
  cmd.time = std::isfinite(s.time) ? s.time : second_.time;
  SecondHand& h = second_;
  const bool grasper = scene_.cut && scene_.cut->grasper;
  if (!grasper || !h.safety.AcceptInput(s, cmd.events)) {
    // Bad input (or no grasper to drive): zero force and the jaws open at once, as a dropped
    // instrument's; the patch is let go of through the fade (SecondHandStep), never a step.
    if (h.closed) h.fading = true;
    h.closed = false;
    h.safety.Disarm();
    h.force.setZero();
    cmd.local.position0 = s.position.allFinite() ? s.position : Vec3::Zero();
    return cmd;
  }
  CountSecondHandEnergy(s);
  const double step = h.has_time ? s.time - h.time : 0;
  const double dt = step > 0 && step < 0.1 ? step : 1e-3;
  h.time = s.time, h.has_time = true;
  h.last_seen = trial_time_;
  SecondHandJaws(s, cmd.events);
  const CutRoom& room = std::get<CutRoom>(room_);
  const Vec3 pull = h.closed ? room.HoldForce() : Vec3::Zero();
  const Vec3 out = h.safety.Filter(pull.allFinite() ? pull : Vec3::Zero(), dt, cmd.events);
  h.force = out;
  h.peak_force = std::max(h.peak_force, out.norm());
  cmd.force = out;
  cmd.local.position0 = s.position;
  // The station renders the jaws' spring about the answer while it waits for the next one.
  if (h.closed) cmd.local.jacobian = -scene_.cut->grasper->stiffness * Eigen::Matrix3d::Identity();
  h.safety.LimitLocalModel(cmd.local, out, cmd.events);
  cmd.grasping = h.closed;
  cmd.contact = h.closed;
  cmd.proxy = s.position;
  cmd.released_j = h.released_j;
  cmd.absorbed_j = h.absorbed_j;
  PublishInput();
  return cmd;
}

// The jaws: closing within reach of the patch (its rest plane, inside its frame) takes the point
// under them; opening lets go at once; while closed they hold toward the hand's tip.
void Simulation::SecondHandJaws(const StylusSample& s, uint32_t& events) {
  SecondHand& h = second_;
  const Scene::CutSpec::Grasper& g = *scene_.cut->grasper;
  const bool button = (s.buttons & haptics::kButtonGrasp) != 0;
  if (h.closed && !button) {
    h.closed = false, h.weight = 0, h.fading = false;
    events |= haptics::kEventGraspEnd;
  }
  const tissue::CutMembraneParams& m = scene_.mesh.membrane;
  const bool over = std::abs(s.position.x()) < 0.5 * m.size_x &&
                    std::abs(s.position.y()) < 0.5 * m.size_y &&
                    std::abs(s.position.z()) <= g.reach;
  if (!h.closed && button && over && !h.fading) {
    h.closed = true, h.weight = 1;
    h.at = Vec3(s.position.x(), s.position.y(), 0);
    ++h.grasps;
    events |= haptics::kEventGraspStart;
  }
  h.target = s.position;
  input_.hold_at = h.at;
  input_.hold_target = h.target;
  input_.hold_stiffness = h.weight * g.stiffness;
}

// On the first hand's samples: a hold whose hand has been silent for kSecondHandSilenceS fades
// out over kSecondHandFadeS (the patch eases back, the blade's hand feels no jolt), its jaws
// staying where they were last heard.
void Simulation::SecondHandStep(double dt) {
  if (!scene_.cut || !scene_.cut->grasper) return;
  SecondHand& h = second_;
  if (h.closed && h.last_seen >= 0 && trial_time_ - h.last_seen > kSecondHandSilenceS)
    h.closed = false, h.fading = true;
  if (!h.fading) return;
  h.weight = std::max(0.0, h.weight - dt / kSecondHandFadeS);
  if (h.weight == 0) h.fading = false;
  input_.hold_stiffness = h.weight * scene_.cut->grasper->stiffness;
}

void Simulation::CountSecondHandEnergy(const StylusSample& s) {
  SecondHand& h = second_;
  if (h.has_x) {
    const double w = h.force.dot(s.position - h.x);
    if (std::isfinite(w)) (w > 0 ? h.released_j : h.absorbed_j) += std::abs(w);
  }
  h.x = s.position, h.has_x = true;
}

}  // namespace vsurg::sim
