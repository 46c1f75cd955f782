// The pattern-cutting drill's loop (cut_drill.h): a scripted hand, the blade at 1 kHz, the cut
// the blade makes handed to the patch as it grows, the patch stepped, the cut scored.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "common/sim/cut_drill.h"
#include "common/sim/cut_trainee.h"

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
  auto blade = BladeOnPatch(spec.blade, *patch);
  if (!blade.ok()) return blade.error();
  CutDrillResult r;
  r.cutting_force = blade->CuttingForce(), r.puncture_force = blade->PunctureForce();
  scoring::CutRecorder rec(spec.task.pattern);
  CutScript script(spec.task.pattern, hand, blade->Reach());
  const int max_steps = static_cast<int>(spec.task.time_limit / kDt);
  std::vector<double> blade_us, tissue_us;
  blade_us.reserve(max_steps), tissue_us.reserve(max_steps);
  haptics::CrackFeed feed;
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
      return true;
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
