// NeedleModel (needle.h): the tract's boundaries, the touch, the pop, the shaft's friction and
// the cutting front, in the order Step takes them.
#include "common/haptics/needle.h"

#include <algorithm>
#include <cmath>

namespace vsurg::haptics {

namespace {

Status CheckLaw(const PunctureLaw& law, const std::string& field) {
  if (!(std::isfinite(law.a1) && law.a1 >= 0))
    return InvalidArgument(field + ".a1", "must be a finite stiffness >= 0 N/m");
  if (!(std::isfinite(law.a2) && law.a2 >= 0))
    return InvalidArgument(field + ".a2", "must be finite and >= 0 N/m^2");
  if (!(law.a1 > 0 || law.a2 > 0))
    return InvalidArgument(field + ".a1", "a boundary needs a stiffness (a1 or a2 > 0)");
  if (!(std::isfinite(law.puncture) && law.puncture > 0 && law.puncture <= 50))
    return InvalidArgument(field + ".puncture", "must be within (0, 50] N");
  return Status::Ok();
}

Status CheckLayer(const NeedleLayer& l, const std::string& f) {
  if (!(std::isfinite(l.thickness) && l.thickness > 0 && l.thickness <= 1))
    return InvalidArgument(f + ".thickness", "must be within (0, 1] m");
  if (Status st = CheckLaw(l.top, f + ".top"); !st) return st;
  const std::pair<double, const char*> laws[] = {{l.friction_static, ".friction_static"},
                                                 {l.friction_sliding, ".friction_sliding"},
                                                 {l.friction_viscous, ".friction_viscous"},
                                                 {l.cutting, ".cutting"},
                                                 {l.lateral_stiffness, ".lateral_stiffness"}};
  for (const auto& [v, name] : laws)
    if (!(std::isfinite(v) && v >= 0 && v <= 1e6))
      return InvalidArgument(f + name, "must be finite, >= 0 and <= 1e6");
  if (l.friction_sliding > l.friction_static)
    return InvalidArgument(f + ".friction_sliding",
                           "must not exceed friction_static (Karnopp: the static limit is the "
                           "larger)");
  return Status::Ok();
}

int LayerAt(const NeedleTissueSpec& spec, double below) {
  double top = 0;
  for (int i = 0; i + 1 < static_cast<int>(spec.layers.size()); ++i) {
    top += spec.layers[i].thickness;
    if (below < top) return i;
  }
  return static_cast<int>(spec.layers.size()) - 1;
}

}  // namespace

Status CheckNeedleTissue(const NeedleTissueSpec& s) {
  if (s.layers.empty() || s.layers.size() > kMaxNeedleLayers)
    return InvalidArgument("needle.layers", "must list 1 to " + std::to_string(kMaxNeedleLayers) +
                                                " layers, from the skin down");
  for (size_t i = 0; i < s.layers.size(); ++i)
    if (Status st = CheckLayer(s.layers[i], "needle.layers[" + std::to_string(i) + "]"); !st)
      return st;
  if (!(std::isfinite(s.surface_z) && std::isfinite(s.centre_x) && std::isfinite(s.centre_y)))
    return InvalidArgument("needle.surface", "must be finite");
  if (!(s.half_x > 0 && s.half_x <= 1 && s.half_y > 0 && s.half_y <= 1))
    return InvalidArgument("needle.surface", "half sizes must be within (0, 1] m");
  if (!(s.velocity_deadzone > 0 && s.velocity_deadzone <= 0.1))
    return InvalidArgument("needle.velocity_deadzone", "must be within (0, 0.1] m/s");
  if (!(s.stick_stiffness > 0 && s.stick_stiffness <= 1e4))
    return InvalidArgument("needle.stick_stiffness", "must be within (0, 1e4] N/m");
  if (!(s.max_entry_angle > 0 && s.max_entry_angle < 1.5707963267948966))
    return InvalidArgument("needle.max_entry_angle", "must be within (0, 90) degrees");
  if (!s.has_target) return Status::Ok();
  const NeedleTarget& t = s.target;
  if (!(t.centre.allFinite() && t.centre.z() < s.surface_z))
    return InvalidArgument("needle.target.centre", "must be finite and under the skin");
  if (!(std::isfinite(t.radius) && t.radius > 0.0005 && t.radius <= 0.05))
    return InvalidArgument("needle.target.radius", "must be within (0.5, 50] mm");
  if (t.centre.z() + t.radius >= s.surface_z)
    return InvalidArgument("needle.target.depth", "the target must lie wholly under the skin");
  if (t.kind == NeedleTarget::Kind::kVessel && !(t.axis.allFinite() && t.axis.norm() > 0.5))
    return InvalidArgument("needle.target.axis", "must be a direction");
  return CheckLaw(t.wall, "needle.target.wall");
}

Expected<NeedleModel> NeedleModel::Create(NeedleTissueSpec spec) {
  if (Status st = CheckNeedleTissue(spec); !st) return st.error();
  spec.target.axis.normalize();
  return NeedleModel(std::move(spec));
}

// The boundaries along the tract: each layer's top where the line crosses its plane, and the
// target's front and back walls where it crosses the target; a layer's plane inside the target
// is no boundary (the lumen is one medium). Sorted by depth; the medium after each one.
void NeedleModel::FindBoundaries() {
  count_ = 0;
  if (state_.phase == NeedleState::Phase::kFree) return;
  const Vec3 e = state_.entry, d = state_.direction;
  const double cos_down = std::max(-d.z(), 1e-6);
  double front = -1, back = -1;
  if (spec_.has_target) {
    const NeedleTarget& t = spec_.target;
    Vec3 q = e - t.centre, r = d;
    if (t.kind == NeedleTarget::Kind::kVessel)
      q -= q.dot(t.axis) * t.axis, r -= r.dot(t.axis) * t.axis;
    const double a = r.squaredNorm(), b = q.dot(r), c = q.squaredNorm() - t.radius * t.radius;
    if (a > 1e-12 && b * b - a * c > 0) {
      const double root = std::sqrt(b * b - a * c);
      front = (-b - root) / a, back = (-b + root) / a;
      if (back <= 0) front = back = -1;  // behind the entry
    }
  }
  double top = 0;
  for (int i = 0; i < static_cast<int>(spec_.layers.size()); ++i) {
    const double depth = top / cos_down;
    top += spec_.layers[i].thickness;
    if (front >= 0 && depth > front && depth < back) continue;
    bounds_[count_++] = {depth, spec_.layers[i].top, i, 0};
  }
  if (front > 0) {
    bounds_[count_++] = {front, spec_.target.wall, static_cast<int32_t>(NeedleMedium::kLumen),
                         NeedleBoundary::kRoleTargetFront};
    const double below = (e + back * d).z();
    bounds_[count_++] = {back, spec_.target.wall, LayerAt(spec_, spec_.surface_z - below + 1e-9),
                         NeedleBoundary::kRoleTargetBack};
  }
  std::sort(bounds_.begin(), bounds_.begin() + count_,
            [](const NeedleBoundary& x, const NeedleBoundary& y) { return x.depth < y.depth; });
  // A layer's top after the back wall leads into that layer; after the front wall every layer
  // boundary was dropped above, so the order is layer tops, front, back, layer tops.
}

NeedleForce NeedleModel::Step(const Vec3& tip, const Vec3& axis, double dt) {
  if (!tip.allFinite() || !axis.allFinite() || !(axis.norm() > 0.5) || !(dt > 0 && dt < 1))
    return {};
  const Vec3 u = axis.normalized();
  NeedleForce out;
  if (state_.phase == NeedleState::Phase::kFree) Touch(tip, u);
  if (state_.phase == NeedleState::Phase::kTouching) out = Touching(tip, u);
  if (state_.phase == NeedleState::Phase::kInserted) {
    const bool popped = out.popped;  // one boundary gives way per step: the next one after it
    const bool redirected = !popped && Redirect(tip, u);
    out = Inserted(tip, dt, !popped);
    out.popped = out.popped || popped;
    out.redirected = redirected;
  }
  last_tip_ = tip;
  has_last_tip_ = true;
  return out;
}

// A free tip that crosses the skin within its rectangle from above begins a tract there: along
// an earlier tract that leaves from here in this direction (it is entered without a puncture),
// or a new one, touching the skin until it gives way.
bool NeedleModel::Touch(const Vec3& tip, const Vec3& u) {
  const double h = spec_.surface_z - tip.z();
  const bool crossed = h > 0 && has_last_tip_ && spec_.surface_z - last_tip_.z() <= 0;
  if (!crossed) return false;
  const double w = (spec_.surface_z - last_tip_.z()) / (tip.z() - last_tip_.z());  // in [0, 1]
  const Vec3 at = last_tip_ + std::clamp(w, 0.0, 1.0) * (tip - last_tip_);
  if (std::abs(at.x() - spec_.centre_x) > spec_.half_x ||
      std::abs(at.y() - spec_.centre_y) > spec_.half_y)
    return false;
  if (Follow(at, u, tip)) return true;
  const bool steep = -u.z() >= std::cos(spec_.max_entry_angle);
  state_.phase = NeedleState::Phase::kTouching;
  state_.tract = ++state_.begun;
  state_.entry = at;
  state_.direction = steep ? u : Vec3(-Vec3::UnitZ());
  state_.passed = 0;
  state_.cut = state_.anchor = state_.last_depth = state_.velocity = 0;
  FindBoundaries();
  return true;
}

// An earlier tract leaving from `entry` along `u` (within kReuseRadius and kReuseAngle), taken up
// again with the tip at `tip`: inserted, its punctures and its cut as they were left.
bool NeedleModel::Follow(const Vec3& entry, const Vec3& u, const Vec3& tip) {
  for (uint32_t i = 0; i < memory_count_; ++i) {
    const NeedleState& m = memory_[i];
    if (m.tract == state_.tract && state_.phase != NeedleState::Phase::kFree) continue;
    if ((m.entry - entry).norm() > kReuseRadius || m.direction.dot(u) < std::cos(kReuseAngle))
      continue;
    const uint32_t begun = state_.begun;
    const double velocity = state_.phase == NeedleState::Phase::kFree ? 0.0 : state_.velocity;
    state_ = m;
    state_.begun = begun;
    state_.phase = NeedleState::Phase::kInserted;
    state_.anchor = state_.last_depth = (tip - m.entry).dot(m.direction);
    state_.velocity = velocity;
    FindBoundaries();
    return true;
  }
  return false;
}

// Redirection without leaving the skin (needle.h): the tract turns about the skin's hole when the
// tip is shallow enough and the needle, turned far enough with its tip from the line, advances.
bool NeedleModel::Redirect(const Vec3& tip, const Vec3& u) {
  const Vec3 d = state_.direction;
  if (u.dot(d) >= std::cos(kRedirectAngle) || -u.z() < std::cos(spec_.max_entry_angle))
    return false;
  const double s = (tip - state_.entry).dot(d);
  const double shallow = count_ > 2 ? bounds_[2].depth : 1e9;
  if (s <= 0 || s >= shallow || ((tip - state_.entry) - s * d).norm() < kRedirectOffset)
    return false;
  // Only advancing: a needle turned in place has cut nothing new yet.
  if (!has_last_tip_ || (tip - last_tip_).dot(u) < kRedirectAdvance) return false;
  const uint32_t was_open = state_.passed;
  Remember();
  if (Follow(state_.entry, u, tip)) return true;
  state_.tract = ++state_.begun;
  state_.direction = u;
  FindBoundaries();
  // Open already: the skin, and the boundary under it when the old tract had punctured it and the
  // tip is past it on the new line (the skin's underside, pierced at the same hole); a target's
  // wall is never opened this way.
  const double s_new = (tip - state_.entry).dot(u);
  state_.passed = 1;
  if (was_open >= 2 && count_ > 1 && bounds_[1].role == 0 && bounds_[1].depth < s_new)
    state_.passed = 2;
  state_.cut = state_.anchor = state_.last_depth = std::max(s_new, 0.0);
  return true;
}

// The skin dimpled by the tip, until its puncture force: the stiffness law along the tract, and
// the dimple holding the tip across it at the law's own slope. A needle too flat to the skin
// slides on it and never punctures it.
NeedleForce NeedleModel::Touching(const Vec3& tip, const Vec3& u) {
  NeedleForce out;
  const Vec3 d = state_.direction;
  const double w = (tip - state_.entry).dot(d);
  if (w <= 0) {  // lifted off before it punctured: no tract is left
    state_.phase = NeedleState::Phase::kFree;
    count_ = 0;
    return out;
  }
  const PunctureLaw& law = bounds_[0].law;
  const double f = law.At(w);
  if (f >= law.puncture && -u.z() >= std::cos(spec_.max_entry_angle)) {
    state_.phase = NeedleState::Phase::kInserted;
    state_.passed = 1;
    // The membrane's release runs the crack to the tip: what lies behind it is cut.
    state_.anchor = state_.last_depth = state_.cut = w;
    ++punctures_;
    out.popped = true;
    return out;
  }
  const Vec3 across = (tip - state_.entry) - w * d;
  const double slope = std::min(law.a1 + 2 * law.a2 * w, spec_.stick_stiffness);
  out.force = -f * d - slope * across;
  out.in_tissue = true;
  out.depth = w;
  out.lateral = across.norm();
  return out;
}

// What the shaft held by punctured tissue (length `held` from the entry) resists with: the
// Karnopp limits' sums over each medium's length, and the lateral stiffness. Returns the static
// limit D (N).
double NeedleModel::ShaftLaws(double held, double& lateral_k, double& coulomb,
                              double& viscous) const {
  double statik = 0;
  lateral_k = coulomb = viscous = 0;
  for (uint32_t i = 0; i < state_.passed && static_cast<int>(i) < count_; ++i) {
    const double from = bounds_[i].depth;
    const double to =
        static_cast<int>(i) + 1 < count_ ? std::min(bounds_[i + 1].depth, held) : held;
    if (to <= from || bounds_[i].after < 0) continue;  // beyond the tip, or the lumen's blood
    const NeedleLayer& l = spec_.layers[bounds_[i].after];
    const double len = to - from;
    statik += l.friction_static * len;
    coulomb += l.friction_sliding * len;
    viscous += l.friction_viscous * len;
    lateral_k += l.lateral_stiffness * len;
  }
  lateral_k = std::min(lateral_k, spec_.stick_stiffness);
  return statik;
}

// The shaft's friction along the tract (a signed force along it, N): the anchor's spring within
// Karnopp's limit, static inside the velocity's dead zone.
double NeedleModel::Friction(double depth, double held, double dt, double& lateral_k) {
  const double raw = (depth - state_.last_depth) / dt;
  state_.velocity += (raw - state_.velocity) * dt / (kVelocityTau + dt);
  double coulomb = 0, viscous = 0;
  const double statik = ShaftLaws(held, lateral_k, coulomb, viscous);
  const double v = std::abs(state_.velocity);
  const double limit = v > spec_.velocity_deadzone ? coulomb + viscous * v : statik;
  const double k = spec_.stick_stiffness;
  double f = -k * (depth - state_.anchor);
  if (std::abs(f) > limit) {
    f = std::copysign(limit, f);
    state_.anchor = depth + f / k;
  }
  return f;
}

// In the tissue: the next boundary pressed (and its pop), the cutting front, the shaft's
// friction and the tissue holding it across; drawn back out of the skin, the tract is left.
NeedleForce NeedleModel::Inserted(const Vec3& tip, double dt, bool may_pop) {
  NeedleForce out;
  const Vec3 d = state_.direction;
  const double s = (tip - state_.entry).dot(d);
  if (s < -kReuseRadius) {
    Remember();
    state_.phase = NeedleState::Phase::kFree;
    count_ = 0;
    return out;
  }
  double press = 0, ahead = 1e9;
  if (static_cast<int>(state_.passed) < count_) {
    const NeedleBoundary& b = bounds_[state_.passed];
    ahead = b.depth;
    if (s > b.depth && (press = b.law.At(s - b.depth)) >= b.law.puncture && may_pop) {
      out.popped = true;
      out.entered_target = (b.role & NeedleBoundary::kRoleTargetFront) != 0;
      out.breached_back_wall = (b.role & NeedleBoundary::kRoleTargetBack) != 0;
      ++state_.passed, ++punctures_;
      state_.cut = std::max(state_.cut, s);  // the release runs the crack to the tip
      press = 0;
      ahead = static_cast<int>(state_.passed) < count_ ? bounds_[state_.passed].depth : 1e9;
    }
  }
  const double held = std::clamp(s, 0.0, ahead);
  // The medium the tip is in: beyond the deepest punctured boundary above it (a tip drawn back
  // through a punctured wall is in the medium before it again).
  uint32_t at = state_.passed;
  while (at > 1 && bounds_[at - 1].depth > s) --at;
  const int32_t medium = at > 0 ? bounds_[at - 1].after : 0;
  double cutting = 0;
  if (medium < 0) {
    state_.cut = std::max(state_.cut, held);  // the lumen: nothing to cut
  } else if (held > state_.cut) {
    const double limit = spec_.layers[medium].cutting, k = spec_.stick_stiffness;
    cutting = k * (held - state_.cut);
    if (cutting > limit) cutting = limit, state_.cut = held - limit / k;
  }
  double lateral_k = 0;
  const double friction = Friction(s, held, dt, lateral_k);
  state_.last_depth = s;
  const Vec3 across = (tip - state_.entry) - s * d;
  out.force = (friction - press - cutting) * d - lateral_k * across;
  out.in_tissue = true;
  out.depth = s;
  out.lateral = across.norm();
  out.strain = out.lateral / std::max(held, 1e-3);
  out.cutting_force = cutting;
  out.in_target = medium < 0;
  return out;
}

bool NeedleModel::TargetOnTract(double& middle, double& deviation, int& needed) const {
  if (!spec_.has_target || state_.phase == NeedleState::Phase::kFree) return false;
  const NeedleTarget& t = spec_.target;
  Vec3 q = state_.entry - t.centre, r = state_.direction;
  if (t.kind == NeedleTarget::Kind::kVessel)
    q -= q.dot(t.axis) * t.axis, r -= r.dot(t.axis) * t.axis;
  // The nearest approach of q + m·r to the origin; a tract along the vessel's axis has none (r
  // is zero): its entry's distance then.
  middle = r.squaredNorm() > 1e-12 ? -q.dot(r) / r.squaredNorm() : 0.0;
  deviation = (q + middle * r).norm();
  needed = 0;
  while (needed < count_ && bounds_[needed].depth < middle) ++needed;
  return true;
}

std::vector<NeedleState> NeedleModel::Tracts() const {
  std::vector<NeedleState> out(memory_.begin(), memory_.begin() + memory_count_);
  const bool current = state_.phase == NeedleState::Phase::kInserted &&
                       std::none_of(out.begin(), out.end(),
                                    [&](const NeedleState& m) { return m.tract == state_.tract; });
  if (current) out.push_back(state_);
  return out;
}

void NeedleModel::Remember() {
  NeedleState m = state_;
  m.phase = NeedleState::Phase::kInserted;
  for (uint32_t i = 0; i < memory_count_; ++i)
    if (memory_[i].tract == m.tract) {
      memory_[i] = m;
      return;
    }
  if (memory_count_ == kMaxTracts) {  // the oldest is forgotten
    std::move(memory_.begin() + 1, memory_.end(), memory_.begin());
    --memory_count_;
  }
  memory_[memory_count_++] = m;
}

void NeedleModel::Adopt(const NeedleState& s) {
  state_ = s;
  FindBoundaries();
  if (static_cast<int>(state_.passed) > count_) state_.passed = count_;
}

bool NeedleModel::Restored() {
  const auto valid = [](const NeedleState& s) {
    return static_cast<uint32_t>(s.phase) <= 2 && s.direction.allFinite() &&
           std::abs(s.direction.norm() - 1) < 1e-6 && s.direction.z() < 0 &&
           s.passed <= static_cast<uint32_t>(kMaxBoundaries) && s.entry.allFinite();
  };
  if (memory_count_ > static_cast<uint32_t>(kMaxTracts) || !valid(state_)) return false;
  for (uint32_t i = 0; i < memory_count_; ++i)
    if (!valid(memory_[i])) return false;
  FindBoundaries();
  return static_cast<int>(state_.passed) <= std::max(count_, 0) ||
         state_.phase == NeedleState::Phase::kFree;
}

}  // namespace vsurg::haptics
