// Simulation's needle (haptics/needle.h, scoring/needle.h): a needle scene's tool is a needle,
// whose tip is the stylus's and whose shaft runs up the stylus (the instrument's frame: the
// shaft along +z toward the hand). The haptic path asks the needle model instead of the proxy;
// the deformation sees the needle's force on the skin at the tract's entry, so the skin dimples
// before it gives way and is dragged by the shaft after; the trial records where the tip went.
#include "common/sim/rooms/room_support.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;

Status Simulation::BuildNeedle() {
  if (!scene_.needle) return Status::Ok();
  auto model = haptics::NeedleModel::Create(*scene_.needle);
  if (!model.ok()) return model.error();
  needle_.model = std::move(*model);
  station_needle_ = std::make_shared<const haptics::NeedleTissueSpec>(needle_.model->spec());
  return Status::Ok();
}

// Haptic thread: the needle's force and the pop; the local model is the needle's state, which a
// station renders with its own copy of the model.
void Simulation::NeedleStep(const Snapshot& snap, const haptics::StylusSample& s,
                            StylusStep& step) {
  const Vec3 axis = -(s.orientation.normalized() * Vec3::UnitZ());
  const haptics::NeedleForce f = needle_.model->Step(s.position, axis, step.dt);
  step.force = f.force;
  step.jacobian.setZero();
  if (f.popped) step.events |= haptics::kEventPunctured;
  if (f.breached_back_wall) step.events |= haptics::kEventBackWall, ++needle_.breaches;
  haptics::LocalModel& local = step.cmd.local;
  local.kind = haptics::LocalModel::Kind::kNeedle;
  local.needle = needle_.model->state();
  step.cmd.contact = f.in_tissue;
  step.cmd.proxy = s.position;
  step.quantity = f.depth;
  NeedleDeform(snap, f);
  NeedleRecord(f, s, step);
}

// The deformation's input: the needle's force on the skin at the tract's entry, as a contact
// there whose coupling spring carries that force (the reduced contact's own input: the tissue
// pulled toward `hip`, hip = p₀ + F/k), so the skin dimples under the tip and follows the shaft.
void Simulation::NeedleDeform(const Snapshot& snap, const haptics::NeedleForce& f) {
  const haptics::NeedleState& st = needle_.model->state();
  if (!f.in_tissue || st.phase == haptics::NeedleState::Phase::kFree) {
    input_.triangle = -1;
    input_.force_on_tissue.setZero();
    return;
  }
  if (needle_.face_tract != st.tract) {  // once per tract: the skin's face under its entry
    const geometry::ClosestHit hit = snap.bvh.Closest(snap.positions, st.entry, 0.01);
    needle_.face = hit.triangle;
    needle_.face_barycentric = hit.barycentric;
    needle_.face_tract = st.tract;
    ++input_.contact_id;
  }
  if (needle_.face < 0) return;
  const double k = proxy_.params().stiffness;
  input_.triangle = needle_.face;
  input_.barycentric = needle_.face_barycentric;
  input_.force_on_tissue = -f.force;
  input_.hip = RestPoint(rest_, needle_.face, needle_.face_barycentric) - f.force / k;
}

// The trial's needle record: the tip against the target along its tract, and a confirmation
// (the mark button's press) that the tip is in the target.
void Simulation::NeedleRecord(const haptics::NeedleForce& f, const haptics::StylusSample& trainee,
                              StylusStep& step) {
  scoring::NeedleSample sample;
  sample.inserted = needle_.model->state().phase == haptics::NeedleState::Phase::kInserted;
  sample.in_target = f.in_target;
  sample.strain = f.strain;
  double middle = 0;
  if (needle_.model->TargetOnTract(middle, sample.path_deviation, sample.needed))
    sample.depth_error = std::abs(f.depth - middle);
  needle_.record.Add(sample);
  const bool mark = (trainee.buttons & haptics::kButtonMark) != 0;
  if (mark && !mark_button_ && needle_.record.Confirm(trial_time_, sample))
    step.events |= haptics::kEventMarked;
  mark_button_ = mark;
}

}  // namespace vsurg::sim
