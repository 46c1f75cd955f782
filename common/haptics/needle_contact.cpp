#include "common/haptics/needle_contact.h"

namespace vsurg::haptics {

namespace {

// What the two sides must agree on: the tract, its phase and the punctures along it.
bool SameCourse(const NeedleState& a, const NeedleState& b) {
  return a.tract == b.tract && a.phase == b.phase && a.passed == b.passed;
}

}  // namespace

NeedleContact::NeedleContact(std::shared_ptr<const NeedleTissueSpec> spec, double period_s)
    : period_(period_s) {
  if (!spec) return;
  auto model = NeedleModel::Create(*spec);
  if (model.ok()) model_ = std::move(*model);
}

Vec3 NeedleContact::Render(const Vec3& tip, const Vec3& axis, uint64_t next_sequence) {
  if (!model_) return Vec3::Zero();
  const NeedleState before = model_->state();
  const NeedleForce f = model_->Step(tip, axis, period_);
  if (!SameCourse(before, model_->state())) changed_at_ = next_sequence;
  local_pops_ += f.popped;
  return f.force;
}

void NeedleContact::Answer(const LocalModel& local, uint64_t echo_sequence) {
  if (!model_ || local.kind != LocalModel::Kind::kNeedle) return;
  const NeedleState& mine = model_->state();
  const NeedleState& theirs = local.needle;
  if (SameCourse(mine, theirs) || echo_sequence < changed_at_) return;
  NeedleState taken = theirs;
  if (theirs.tract == mine.tract && mine.phase != NeedleState::Phase::kFree) {
    taken.anchor = mine.anchor, taken.last_depth = mine.last_depth;
    taken.velocity = mine.velocity, taken.cut = std::max(mine.cut, theirs.cut);
  }
  model_->Adopt(taken);
  ++corrections_;
}

}  // namespace vsurg::haptics
