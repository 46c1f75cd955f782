// The pattern-cutting drill's loop (cut_drill.h): a scripted hand, the blade at 1 kHz, the cut
// the blade makes handed to the patch as it grows, the patch stepped, the cut scored.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "common/sim/cut_drill.h"

namespace vsurg::sim {

namespace {

using Clock = std::chrono::steady_clock;
using geometry::Vec3;
using tissue::Vec2;
constexpr double kDt = 1e-3;  // s

double Us(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

StageTimes Summarise(std::vector<double>& v) {
  StageTimes s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.p50_us = v[v.size() / 2];
  s.p99_us = v[std::min(v.size() - 1, v.size() * 99 / 100)];
  s.max_us = v.back();
  return s;
}

// The scripted hand: above the pattern's start, pressed down until the blade is through, drawn
// along the pattern (a line a millimetre and the blade's reach past its end, a circle a twentieth
// of a turn past its start) with its wobble, lifted out and put back in `lifts` times, and lifted
// at the end for the patch to settle.
class ScriptedCut {
 public:
  // `reach`: how far the blade runs ahead of its cut (BladeModel::Reach), which a line's end needs
  // beyond it.
  ScriptedCut(const scoring::CutPattern& p, const CutHand& h, double reach) : p_(p), h_(h) {
    std::mt19937 rng(h.seed);
    std::uniform_real_distribution<double> phase(0, 2 * std::numbers::pi);
    phi1_ = phase(rng), phi2_ = phase(rng);
    total_ = p.kind == scoring::CutPattern::Kind::kCircle ? 1.05 * p.Length()
                                                          : p.Length() + reach + 1e-3;
  }
  bool done() const { return phase_ == Phase::kDone; }
  // The tip after one step, told whether the blade is through now.
  Vec3 Next(bool through) {
    switch (phase_) {
      case Phase::kApproach:
        if ((t_ += kDt) > 0.3) phase_ = Phase::kPress;
        return Tip(0.002);
      case Phase::kPress:
        if (through) phase_ = Phase::kDraw;
        z_ = std::max(z_ - 0.02 * kDt, -0.02);
        return Tip(z_);
      case Phase::kDraw:
        return Draw(through);
      case Phase::kLift:
        if ((t_ += kDt) > 0.3) phase_ = Phase::kPress, z_ = 0.0;
        return Tip(0.001);
      case Phase::kEnd:  // lifted out, the patch left to settle
        if ((t_ += kDt) > 0.3) phase_ = Phase::kDone;
        return Tip(0.002);
      case Phase::kDone:
        break;
    }
    return Tip(0.002);
  }

 private:
  enum class Phase { kApproach, kPress, kDraw, kLift, kEnd, kDone };
  Vec3 Draw(bool through) {
    s_ += h_.speed * kDt;
    const double lift_every = total_ / (h_.lifts + 1);
    if (h_.lifts > 0 && lifted_ < h_.lifts && s_ > (lifted_ + 1) * lift_every) {
      ++lifted_, t_ = 0, phase_ = Phase::kLift;
      return Tip(0.001);
    }
    if (s_ >= total_) phase_ = Phase::kEnd, t_ = 0;
    (void)through;
    return Tip(z_);
  }
  Vec3 Tip(double z) const {
    const double u = s_ / p_.Length();
    double x = 0, y = 0, x2 = 0, y2 = 0;
    const double e = 1e-4 / p_.Length();
    if (p_.kind == scoring::CutPattern::Kind::kLine) {
      const double dx = (p_.bx - p_.ax) / p_.Length(), dy = (p_.by - p_.ay) / p_.Length();
      x = p_.ax + s_ * dx, y = p_.ay + s_ * dy, x2 = x + dx, y2 = y + dy;
    } else {
      p_.At(u, x, y), p_.At(u + e, x2, y2);
    }
    const double tx = x2 - x, ty = y2 - y, tl = std::hypot(tx, ty);
    const double w = h_.wobble *
                     (std::sin(2 * std::numbers::pi * s_ / 0.02 + phi1_) +
                      0.5 * std::sin(2 * std::numbers::pi * s_ / 0.007 + phi2_)) /
                     1.5;
    return Vec3(x - w * ty / tl, y + w * tx / tl, z);
  }

  scoring::CutPattern p_;
  CutHand h_;
  Phase phase_ = Phase::kApproach;
  double t_ = 0, z_ = 0, s_ = 0, total_ = 0, phi1_ = 0, phi2_ = 0;
  int lifted_ = 0;
};

// What the blade's crack grew by since the last step, handed to the patch and the recorder.
struct CrackFeed {
  int segment = 0;  // the segment fed up to `x, y`
  double x = 0, y = 0;
  bool started = false;
  template <class F>
  void Take(const haptics::BladeModel& blade, F&& grow) {
    for (; segment < blade.segment_count(); ++segment) {
      const auto& s = blade.segment(segment);
      const double ax = started ? x : s.ax, ay = started ? y : s.ay;
      grow(ax, ay, s.bx, s.by);
      x = s.bx, y = s.by, started = false;
      if (segment + 1 == blade.segment_count()) {
        started = true;  // the last segment may grow further: resume from its end
        break;
      }
    }
  }
};

}  // namespace

namespace {

void KeepShape(const tissue::CutMembrane& patch, const haptics::BladeModel& blade,
               CutDrillTrace& trace) {
  for (int f = 0; f < patch.FaceCount(); ++f) {
    if (patch.Removed(f)) continue;
    const auto v = patch.face(f).v;
    trace.faces.push_back(
        {patch.positions()[v[0]], patch.positions()[v[1]], patch.positions()[v[2]]});
  }
  for (int i = 0; i < blade.segment_count(); ++i) trace.cut.push_back(blade.segment(i));
}

// The left hand's grasper: where it holds (rest plane) and the way it pulls (unit, away from the
// cut), and its jaws' stiffness.
struct Grasp {
  Vec2 at = Vec2::Zero(), away = Vec2::UnitX();
  static constexpr double kStiffness = 2000;  // N/m
  explicit Grasp(const scoring::CutPattern& p) {
    if (p.kind == scoring::CutPattern::Kind::kCircle) {
      at = Vec2(p.cx, p.cy), away = Vec2(-1, 0);  // the piece, pulled toward its far side
    } else {
      const Vec2 a(p.ax, p.ay), b(p.bx, p.by), d = (b - a).normalized();
      away = Vec2(-d.y(), d.x());
      at = 0.5 * (a + b) + 0.006 * away;
    }
  }
  Vec3 Target(const CutHand& h, double t) const {
    const double ramp = std::min(1.0, t);
    const Vec2 xy = at + ramp * h.grasp_pull * away;
    return Vec3(xy.x(), xy.y(), ramp * h.grasp_lift);
  }
};

}  // namespace

Expected<CutDrillResult> RunCutDrill(const CutDrillSpec& spec, const CutHand& hand,
                                     CutDrillTrace* trace) {
  auto patch = tissue::CutMembrane::Create(spec.tissue);
  if (!patch.ok()) return patch.error();
  haptics::BladeParams bp = spec.blade;
  bp.in_plane_stiffness = patch->InPlaneStiffness();
  bp.normal_stiffness = patch->NormalStiffness();
  auto blade = haptics::BladeModel::Create(bp);
  if (!blade.ok()) return blade.error();
  CutDrillResult r;
  r.cutting_force = blade->CuttingForce(), r.puncture_force = blade->PunctureForce();
  scoring::CutRecorder rec(spec.task.pattern);
  ScriptedCut script(spec.task.pattern, hand, blade->Reach());
  const int max_steps = static_cast<int>(spec.task.time_limit / kDt);
  std::vector<double> blade_us, tissue_us;
  blade_us.reserve(max_steps), tissue_us.reserve(max_steps);
  CrackFeed feed;
  const Grasp grasp(spec.task.pattern);
  double err2 = 0;
  int freed = 0;
  for (int step = 0; step < max_steps && !script.done(); ++step) {
    const double t = step * kDt;
    const Vec3 tip = script.Next(blade->through());
    const auto t0 = Clock::now();
    const haptics::BladeForce f = blade->Step(tip);
    const auto t1 = Clock::now();
    feed.Take(*blade, [&](double ax, double ay, double bx, double by) {
      const auto c0 = Clock::now();
      r.cut_edges += patch->Cut(Vec2(ax, ay), Vec2(bx, by));
      r.max_cut_us = std::max(r.max_cut_us, Us(c0, Clock::now()));
      rec.AddCut(ax, ay, bx, by);
    });
    patch->Load(Vec2(tip.x(), tip.y()), -f.force);
    patch->Hold(grasp.at, grasp.Target(hand, t), Grasp::kStiffness);
    if (!patch->Step(kDt)) r.diverged = true;
    const double spare = blade->Reach() + 2 * patch->EdgeLength();
    if (const int tore = patch->Tear(Vec2(tip.x(), tip.y()), spare); tore > 0)
      rec.Torn(tore * patch->EdgeLength());
    r.peak_grasp_force = std::max(r.peak_grasp_force, patch->HoldForce().norm());
    tissue_us.push_back(Us(t1, Clock::now()));
    blade_us.push_back(Us(t0, t1));
    if (!f.through) r.peak_press = std::max(r.peak_press, f.force.norm());
    if (f.cutting) {
      const double e = (f.force.norm() - r.cutting_force) / r.cutting_force;
      err2 += e * e, ++r.cutting_steps;
    }
    rec.AddSample(t, tip.x(), tip.y(), f.through, f.force.norm(), spec.task.force_limit);
    if (trace)
      trace->samples.push_back(
          {t, tip.x(), tip.y(), tip.z(), f.force.norm(), f.through, f.cutting});
    if (patch->freed_pieces() > freed) freed = patch->freed_pieces(), rec.PieceFreed(t);
    r.steps = step + 1;
  }
  r.force_rms_error = r.cutting_steps > 0 ? std::sqrt(err2 / r.cutting_steps) : 1.0;
  r.metrics = rec.Complete(spec.task);
  r.blade = Summarise(blade_us), r.tissue = Summarise(tissue_us);
  r.particles = static_cast<int>(patch->positions().size());
  r.freed = patch->freed_pieces();
  r.torn_length = patch->torn_edges() * patch->EdgeLength();
  if (trace) KeepShape(*patch, *blade, *trace);
  return r;
}

}  // namespace vsurg::sim
