#include "common/sim/needle_trainee.h"

#include <algorithm>
#include <cmath>

namespace vsurg::sim {

namespace {

using geometry::Vec3;

// One move of the hand: to `to` over `seconds` (minimum jerk), with `buttons` held.
struct Move {
  double seconds;
  Vec3 to;
  uint32_t buttons = 0;
};

// A straight insertion's moves: from the entry's `above` point down to `depth` at `speed`.
Move Insert(const Vec3& entry, double depth, double speed, double from_depth) {
  return {std::abs(depth - from_depth) / speed, entry - depth * Vec3::UnitZ()};
}

std::vector<Move> Plan(const haptics::NeedleTissueSpec& n, TraineeStyle style, Vec3& start) {
  const Vec3 c = n.target.centre;
  const double depth = n.surface_z - c.z(), r = n.target.radius;
  const Vec3 entry(c.x(), c.y(), n.surface_z);
  const Vec3 wide = entry + Vec3(r + 0.002, 0, 0);
  const Vec3 up = 0.03 * Vec3::UnitZ(), near = 0.002 * Vec3::UnitZ();
  const uint32_t mark = haptics::kButtonMark;
  switch (style) {
    case TraineeStyle::kHesitant:
      start = wide + up;
      return {{0.5, wide + up},
              {2.0, wide + near},
              Insert(wide, depth + 0.002, 0.004, -0.002),
              {1.0, wide - (depth + 0.002) * Vec3::UnitZ()},  // no flash: nothing there
              {3.0, wide + near},
              {1.0, entry + near},
              Insert(entry, 0.008, 0.004, -0.002),
              {0.5, entry - 0.008 * Vec3::UnitZ()},
              Insert(entry, 0.006, 0.004, 0.008),
              Insert(entry, depth - r - 0.002, 0.004, 0.006),
              {0.2, entry - (depth - r - 0.002) * Vec3::UnitZ(), mark},  // too early
              {0.6, entry - (depth - r - 0.002) * Vec3::UnitZ()},
              Insert(entry, depth + 0.0015, 0.003, depth - r - 0.002),
              {0.4, entry - (depth + 0.0015) * Vec3::UnitZ()},
              {0.2, entry - (depth + 0.0015) * Vec3::UnitZ(), mark},
              {0.5, entry - (depth + 0.0015) * Vec3::UnitZ()},
              {3.0, entry + up}};
    case TraineeStyle::kRough: {
      start = entry + up;
      const Vec3 through = entry - (depth + r + 0.004) * Vec3::UnitZ();
      return {{0.2, entry + up},
              {0.6, entry + near},
              Insert(entry, depth + r + 0.004, 0.03, -0.002),
              {0.3, through + Vec3(0.002, 0, 0)},
              {0.4, entry - depth * Vec3::UnitZ()},
              {0.1, entry - depth * Vec3::UnitZ(), mark},
              {0.2, entry - depth * Vec3::UnitZ()},
              {0.8, entry + up}};
    }
    case TraineeStyle::kGood:
    case TraineeStyle::kSteady:
      break;
  }
  start = entry + up;
  return {{0.3, entry + up},
          {1.0, entry + near},
          Insert(entry, depth, 0.008, -0.002),
          {0.3, entry - depth * Vec3::UnitZ()},
          {0.15, entry - depth * Vec3::UnitZ(), mark},
          {0.5, entry - depth * Vec3::UnitZ()},
          {2.0, entry + up}};
}

}  // namespace

Expected<std::vector<haptics::StylusSample>> NeedleTrainee(const Scene& scene, TraineeStyle style,
                                                           double rate_hz) {
  if (!scene.needle || !scene.needle->has_target)
    return Error{ErrorCode::kFailedPrecondition, "the scene has no needle with a target", "scene"};
  if (!(rate_hz >= 10 && rate_hz <= 100000))
    return InvalidArgument("rate", "rate must be in 10..100000 Hz");
  Vec3 at = Vec3::Zero();
  const std::vector<Move> plan = Plan(*scene.needle, style, at);
  std::vector<haptics::StylusSample> out;
  const double dt = 1.0 / rate_hz;
  double t = 0;
  for (const Move& m : plan) {
    const int n = std::max(1, static_cast<int>(std::round(m.seconds * rate_hz)));
    for (int i = 1; i <= n; ++i) {
      const double tau = static_cast<double>(i) / n;
      const double s = tau * tau * tau * (10 - 15 * tau + 6 * tau * tau);  // minimum jerk
      haptics::StylusSample sample;
      sample.time = (t += dt);
      sample.position = at + s * (m.to - at);
      sample.buttons = m.buttons;  // the needle points down: the stylus frame is the scene's
      out.push_back(sample);
    }
    at = m.to;
  }
  return out;
}

}  // namespace vsurg::sim
