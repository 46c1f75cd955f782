// Stylus trajectories: the CSV replay format and scripted trainees.
//
// CSV: a header line `t,x,y,z,qw,qx,qy,qz,buttons` then one sample per line: seconds, metres
// in the scene frame, a unit quaternion (normalised on read), button bits (1 = grasp). Errors
// give the line and the column.
//
// Scripted trainees perform a scene's task the way three kinds of trainee do, for tests, demos
// and the scoring loop: `good` (minimum-jerk moves to the target, a steady hold), `hesitant`
// (slow, stops short, corrects in small steps, holds too briefly at first), `rough` (fast and
// jerky, overshoots well past the target and loads the tissue beyond the force limit).
#pragma once

#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/haptics/types.h"
#include "common/sim/scene.h"

namespace vsurg::sim {

Expected<std::vector<haptics::StylusSample>> ReadTrajectoryCsv(const std::string& path);
Expected<std::vector<haptics::StylusSample>> ParseTrajectoryCsv(const std::string& text,
                                                                const std::string& source);
Status WriteTrajectoryCsv(const std::vector<haptics::StylusSample>& samples,
                          const std::string& path);

// kSteady: the rough trainee's pace without its overshoot or tremor (an expert's hand guiding a
// rough trainee moves with them: four-handed training's scripted instructor).
enum class TraineeStyle { kGood, kHesitant, kRough, kSteady };
Expected<TraineeStyle> ParseTraineeStyle(const std::string& name);  // good, hesitant, rough, steady

// Minimum-jerk profile from 0 to 1 over u in [0, 1] (clamped outside).
double MinJerk(double u);

// Where the scripted trainees touch a scene (m, in the scene's frame): a point on the rest surface
// inside one face, its outward unit normal, and the twist's axis through axis_point. Errors name
// "scene" (a mesh with no surface above its middle).
struct Touch {
  geometry::Vec3 surface = geometry::Vec3::Zero(), normal = geometry::Vec3::UnitZ();
  geometry::Vec3 axis_point = geometry::Vec3::Zero(), axis = geometry::Vec3::UnitZ();
};
Expected<Touch> ScriptedTouch(const Scene& scene);

// A trajectory at rate_hz samples per second that performs the scene's task. `seed` varies the
// tremor of the rough trainee; the others are deterministic.
Expected<std::vector<haptics::StylusSample>> ScriptedTrainee(const Scene& scene, TraineeStyle style,
                                                             double rate_hz = 1000.0,
                                                             unsigned seed = 1);

}  // namespace vsurg::sim
