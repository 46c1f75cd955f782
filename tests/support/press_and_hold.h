// A scripted stylus for the sphere-palpation scenes, shared by the loopback tests.
#pragma once

#include <algorithm>
#include <vector>

#include "common/haptics/types.h"

namespace vsurg::test {

// 1 kHz samples that approach the 5 cm sphere's top, sink 3 mm in over 0.3 s and hold: a
// steady contact force.
inline std::vector<haptics::StylusSample> PressAndHold(double seconds) {
  std::vector<haptics::StylusSample> out;
  const Eigen::Vector3d dir = Eigen::Vector3d(0.02, 0.03, 1.0).normalized();
  const Eigen::Vector3d above = 0.06 * dir, inside = (0.05 * 0.9 - 0.003) * dir;
  for (int k = 0; k < static_cast<int>(seconds * 1000); ++k) {
    haptics::StylusSample s;
    s.position = above + (inside - above) * std::min(1.0, k / 300.0);
    out.push_back(s);
  }
  return out;
}

}  // namespace vsurg::test
