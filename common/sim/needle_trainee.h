// Scripted needle insertions (trajectory.h's trainees, for a needle scene): three ways trainees
// place a needle in its target, as stylus samples with the needle pointing down its shaft.
//
//   good      aims above the target's centre, enters at a steady 8 mm/s, stops in the middle of
//             the target, confirms, and draws back out;
//   hesitant  first aims 7 mm wide of the target, misses it, draws out and enters again above
//             it; advances at 4 mm/s with pauses and a small draw-back, confirms too early once
//             (short of the target) and then again inside it;
//   rough     enters at 30 mm/s straight through the target's back wall, levers the needle
//             sideways 2 mm, pulls back into the target, confirms, and tugs out.
// Positions are the hand's intent (a replay follows them; a virtual hand is pulled by them).
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/haptics/types.h"
#include "common/sim/scene.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim {

// kFailedPrecondition unless the scene has a needle with a target; kSteady plays the good hand.
Expected<std::vector<haptics::StylusSample>> NeedleTrainee(const Scene& scene, TraineeStyle style,
                                                           double rate_hz = 1000.0);

}  // namespace vsurg::sim
