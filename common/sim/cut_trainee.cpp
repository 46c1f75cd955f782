// A cut scene's scripted trainee (cut_trainee.h).
#include "common/sim/cut_trainee.h"

#include "common/haptics/blade.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::sim {

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

}  // namespace vsurg::sim
