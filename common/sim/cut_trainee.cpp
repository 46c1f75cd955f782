// A cut scene's scripted trainee (cut_trainee.h).
#include "common/sim/cut_trainee.h"

#include <algorithm>

#include "common/haptics/blade.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::sim {

using tissue::Vec2;

namespace {

CutHand HandOf(TraineeStyle style, unsigned seed) {
  switch (style) {
    case TraineeStyle::kGood:
    case TraineeStyle::kSteady:
      return CutHand::Expert(seed);
    case TraineeStyle::kHesitant:
      return CutHand::Novice(seed);
    case TraineeStyle::kRough: {
      CutHand h = CutHand::Novice(seed);
      h.speed *= 2, h.wobble *= 1.5;
      return h;
    }
  }
  return CutHand::Expert(seed);
}

}  // namespace

Expected<std::vector<haptics::StylusSample>> CutTrainee(const Scene& scene, TraineeStyle style,
                                                        double rate_hz, unsigned seed) {
  if (!scene.cut) return Error{ErrorCode::kFailedPrecondition, "the scene has no cut", "scene"};
  if (!(rate_hz >= 10 && rate_hz <= 100000))
    return InvalidArgument("rate", "rate must be in 10..100000 Hz");
  auto patch = tissue::CutMembrane::Create(scene.mesh.membrane);
  if (!patch.ok()) return patch.error();
  auto blade = BladeOnPatch(scene.cut->blade, *patch);
  if (!blade.ok()) return blade.error();
  const double through_at =
      blade->PunctureForce() / blade->params().normal_stiffness + 1e-3;  // m deep
  CutScript script(scene.cut->pattern, HandOf(style, seed), blade->Reach());
  std::vector<haptics::StylusSample> out;
  const double period = 1.0 / rate_hz;
  const int max_steps = static_cast<int>(scene.task.time_limit / CutScript::kDt);
  double next = 0;
  for (int step = 0; step < max_steps && !script.done(); ++step) {
    const geometry::Vec3 tip = script.Next(-script.z() >= through_at);
    const double t = step * CutScript::kDt;
    if (t + 1e-12 < next) continue;
    haptics::StylusSample s;
    s.time = t;
    s.position = tip;
    out.push_back(s);
    next += period;
  }
  return out;
}

Expected<std::vector<haptics::StylusSample>> GrasperTrainee(const Scene& scene,
                                                            const GrasperHold& hold,
                                                            double rate_hz) {
  if (!scene.cut || !scene.cut->grasper)
    return Error{ErrorCode::kFailedPrecondition, "the scene has no grasper", "scene"};
  if (!(rate_hz >= 10 && rate_hz <= 100000))
    return InvalidArgument("rate", "rate must be in 10..100000 Hz");
  if (!(hold.duration > 0 && hold.duration <= 3600) || !std::isfinite(hold.lift) ||
      !std::isfinite(hold.pull))
    return InvalidArgument("duration", "a hold of 0..3600 s with a finite lift and pull");
  const scoring::CutPattern& p = scene.cut->pattern;
  Vec2 at(p.cx, p.cy), away(-1, 0);  // a circle: its piece's middle, pulled toward −x
  if (p.kind == scoring::CutPattern::Kind::kLine) {
    const Vec2 a(p.ax, p.ay), b(p.bx, p.by), d = (b - a).normalized();
    away = Vec2(-d.y(), d.x());
    at = 0.5 * (a + b) + 0.006 * away;  // beside the line, as the drill's left hand
  }
  std::vector<haptics::StylusSample> out;
  const int n = static_cast<int>(hold.duration * rate_hz);
  out.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    haptics::StylusSample s;
    s.time = i / rate_hz;
    const double ramp = std::clamp(s.time - 0.2, 0.0, 1.0);
    const Vec2 xy = at + ramp * hold.pull * away;
    s.position = geometry::Vec3(xy.x(), xy.y(), s.time < 0.1 ? 0.01 : ramp * hold.lift);
    s.buttons = s.time >= 0.15 ? uint32_t{haptics::kButtonGrasp} : 0u;
    s.orientation = Eigen::AngleAxisd(-0.6, Eigen::Vector3d::UnitY());  // in from the left
    out.push_back(s);
  }
  return out;
}

}  // namespace vsurg::sim
