// The pattern-cutting trainee's hand (the drill's, cut_drill.h, and a cut scene's scripted
// trainee): the blade above the pattern's start, pressed in, drawn along the pattern with a
// wobble, lifted out and put back in as the hand's style says, and lifted at the end.
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "common/core/expected.h"
#include "common/haptics/types.h"
#include "common/sim/cut_drill.h"
#include "common/sim/scene.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim {

// The scripted hand: above the pattern's start, pressed down until the blade is through, drawn
// along the pattern (a line a millimetre and the blade's reach past its end, a circle a twentieth
// of a turn past its start) with its wobble, lifted out and put back in `lifts` times, and lifted
// at the end for the patch to settle.
class CutScript {
 public:
  // `reach`: how far the blade runs ahead of its cut (BladeModel::Reach), which a line's end needs
  // beyond it.
  CutScript(const scoring::CutPattern& p, const CutHand& h, double reach) : p_(p), h_(h) {
    std::mt19937 rng(h.seed);
    std::uniform_real_distribution<double> phase(0, 2 * std::numbers::pi);
    phi1_ = phase(rng), phi2_ = phase(rng);
    total_ = p.kind == scoring::CutPattern::Kind::kCircle ? 1.05 * p.Length()
                                                          : p.Length() + reach + 1e-3;
  }
  static constexpr double kDt = 1e-3;  // s, one step of the script
  bool done() const { return phase_ == Phase::kDone; }
  double z() const { return z_; }  // m, the depth it presses to (below the patch: negative)
  // The tip after one step, told whether the blade is through now.
  geometry::Vec3 Next(bool through) {
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
  geometry::Vec3 Draw(bool through) {
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
  geometry::Vec3 Tip(double z) const {
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
    return geometry::Vec3(x - w * ty / tl, y + w * tx / tl, z);
  }

  scoring::CutPattern p_;
  CutHand h_;
  Phase phase_ = Phase::kApproach;
  double t_ = 0, z_ = 0, s_ = 0, total_ = 0, phi1_ = 0, phi2_ = 0;
  int lifted_ = 0;
};

// A cut scene's scripted trainee (trajectory.h): good and steady cut as the drill's expert,
// hesitant as its novice, rough as the novice at twice the speed with a wider wobble. The hand is
// open-loop: it presses the blade 1 mm past the depth at which the blade's model punctures the
// patch (f_p / k_n), then draws. kFailedPrecondition unless the scene is a cut.
Expected<std::vector<haptics::StylusSample>> CutTrainee(const Scene& scene, TraineeStyle style,
                                                        double rate_hz = 1000.0, unsigned seed = 1);

// The second hand of a cut scene with a grasper (Scene::CutSpec::grasper), scripted as FLS's
// counter-traction: from 1 cm above the pattern's middle down onto the patch, the jaws closed at
// 0.15 s, then over a second lifted `lift` m and pulled `pull` m away from the cut (a circle's
// piece toward −x, a line's side away from it), held so for `duration` s. kFailedPrecondition
// unless the scene has a grasper.
struct GrasperHold {
  double lift = 0.003, pull = 0, duration = 30;  // m, m, s
};
Expected<std::vector<haptics::StylusSample>> GrasperTrainee(const Scene& scene,
                                                            const GrasperHold& hold = {},
                                                            double rate_hz = 1000.0);

}  // namespace vsurg::sim
