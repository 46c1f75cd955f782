// Simulation's cut (haptics/blade.h, rooms/cut_room.h, scoring/cut.h): a cut scene's tool is a
// blade whose edge is the stylus's tip. The haptic path asks the blade's fracture-mechanics model
// instead of the proxy: the patch dimples under it until it punctures, then its crack follows
// the tip at the cutting force. Each piece the crack grows by goes to the patch's room, which
// carves it on the deformation side; the blade's force loads the patch at its tip; the trial
// records the cut against the marked pattern.
#include "common/sim/cut_drill.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;

Status Simulation::BuildCut() {
  if (!scene_.cut) return Status::Ok();
  const CutRoom* room = std::get_if<CutRoom>(&room_);
  if (!room) return InvalidArgument("regions[0].model.type", "a cut scene needs the cut room");
  auto blade = BladeOnPatch(scene_.cut->blade, room->patch());
  if (!blade.ok()) return blade.error();
  cut_.blade = std::move(*blade);
  station_blade_ = std::make_shared<const haptics::BladeParams>(cut_.blade->params());
  cut_.record.emplace(scene_.cut->pattern);
  return Status::Ok();
}

// Haptic thread: the blade's force; its crack's new pieces to the room (a piece the full queue
// refuses is offered again next sample); its load on the patch; the trial's record. The station's
// local model is the blade's stiffness where it is: the patch's out-of-plane spring while it
// presses, nothing once through (the crack advances at a constant force).
void Simulation::CutStep(const haptics::StylusSample& s, StylusStep& step) {
  const haptics::BladeForce f = cut_.blade->Step(s.position);
  CutRoom& room = std::get<CutRoom>(room_);
  cut_.feed.Take(*cut_.blade, [&](double ax, double ay, double bx, double by) {
    if (!room.PushCut({ax, ay, bx, by})) return false;
    cut_.record->AddCut(ax, ay, bx, by);
    return true;
  });
  step.force = f.force;
  step.jacobian.setZero();
  const bool loads = f.force.squaredNorm() > 0;
  if (loads && !f.through) step.jacobian(2, 2) = -cut_.blade->params().normal_stiffness;
  if (f.punctured) step.events |= haptics::kEventPunctured;
  input_.triangle = loads ? 0 : -1;
  input_.hip = s.position;
  input_.force_on_tissue = -f.force;
  step.cmd.contact = loads || f.through;
  step.cmd.proxy = s.position;
  step.quantity = scene_.cut->pattern.Distance(s.position.x(), s.position.y());
  CutRecord(f, s);
}

void Simulation::CutRecord(const haptics::BladeForce& f, const haptics::StylusSample& s) {
  const CutRoom& room = std::get<CutRoom>(room_);
  scoring::CutRecorder& rec = *cut_.record;
  rec.AddSample(trial_time_, s.position.x(), s.position.y(), f.through, f.force.norm(),
                scene_.task.force_limit);
  if (const double torn = room.TornLength(); torn > cut_.torn)
    rec.Torn(torn - cut_.torn), cut_.torn = torn;
  if (const int freed = room.FreedPieces(); freed > cut_.freed) {
    cut_.freed = freed;
    rec.PieceFreed(trial_time_);
  }
}

}  // namespace vsurg::sim
