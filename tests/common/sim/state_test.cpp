// A simulation's state carried to a new one (live migration, Simulation::SaveState and
// RestoreState): the trial goes on as if it had never moved, for every kind of tissue model,
// and bytes that are not a state of this scene are refused without harm.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim {
namespace {

using haptics::ForceCommand;
using haptics::StylusSample;

std::unique_ptr<Simulation> Make(const Scene& scene) {
  SimulationOptions o;
  o.threaded = false;
  auto sim = Simulation::Create(scene, o);
  EXPECT_TRUE(sim.ok()) << sim.error().message;
  return sim.ok() ? std::move(sim).value() : nullptr;
}

std::vector<ForceCommand> Play(Simulation& sim, const std::vector<StylusSample>& samples) {
  std::vector<ForceCommand> out;
  sim.Replay(samples, [&](const StylusSample&, const ForceCommand& c) { out.push_back(c); });
  return out;
}

struct Case {
  const char* scene;
  double tolerance_n;     // the continuation's largest force difference from the unmoved trial
  bool relaxing = false;  // the scene's torque relaxes (its internal torques carried too)
};

class StateTest : public ::testing::TestWithParam<Case> {};

// The trial is cut where the task is under way (a grasp held, or the tip in the tissue): the
// first part played on one simulation, its state carried to a new one, the rest played there;
// beside it, the same two parts played on one simulation. The forces after the cut and the
// trial's metrics are the same. The quasi-static models carry exactly; the mass-spring's
// implicit solve starts its warm start afresh, so it differs within its CG tolerance.
TEST_P(StateTest, ATrialCarriedToANewSimulationGoesOnAsIfItHadNotMoved) {
  auto scene = LoadSceneByName(GetParam().scene);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  if (GetParam().relaxing) scene->relaxation = {{0.4, 0.5}};
  auto samples = ScriptedTrainee(*scene, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok()) << samples.error().message;
  // Where the task is under way: the unmoved trial's first grasp or contact, plus 0.3 s; then
  // 0.7 s more is enough to see the trial go on (the whole trial three times took minutes under
  // ASan).
  auto probe = Make(*scene);
  ASSERT_TRUE(probe);
  size_t cut = 0;
  for (bool found = false; !found && cut < samples->size();) {
    const size_t end = std::min(samples->size(), cut + 100);
    const std::vector<StylusSample> chunk(samples->begin() + cut, samples->begin() + end);
    for (const ForceCommand& c : Play(*probe, chunk)) {
      if (c.grasping || c.contact) {
        found = true;
        break;
      }
      ++cut;
    }
  }
  cut += 300;
  ASSERT_LT(cut + 700, samples->size()) << "the trainee never reached the task";
  const std::vector<StylusSample> first(samples->begin(), samples->begin() + cut),
      rest(samples->begin() + cut, samples->begin() + cut + 700);

  auto unmoved = Make(*scene);
  ASSERT_TRUE(unmoved);
  Play(*unmoved, first);
  const std::vector<ForceCommand> expected = Play(*unmoved, rest);

  auto before = Make(*scene);
  ASSERT_TRUE(before);
  const std::vector<ForceCommand> led = Play(*before, first);
  ASSERT_TRUE(led.back().grasping || led.back().contact) << "cut outside the task";
  EXPECT_GT(led.back().force.norm(), 0.05) << "cut where the tissue pushes back";
  const std::string state = before->SaveState();
  auto after = Make(*scene);
  ASSERT_TRUE(after);
  const Status restored = after->RestoreState(state);
  ASSERT_TRUE(restored.ok()) << restored.error().message;
  EXPECT_DOUBLE_EQ(after->trial_time(), before->trial_time());
  const std::vector<ForceCommand> got = Play(*after, rest);

  ASSERT_EQ(got.size(), expected.size());
  double worst = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    worst = std::max(worst, (got[i].force - expected[i].force).norm());
    ASSERT_EQ(got[i].grasping, expected[i].grasping) << "sample " << i << " after the cut";
    ASSERT_EQ(got[i].contact, expected[i].contact) << "sample " << i << " after the cut";
  }
  EXPECT_LE(worst, GetParam().tolerance_n);
  // The first answer after the move is the tissue's, not a start-up gate's ramp from zero.
  EXPECT_NEAR(got.front().force.norm(), expected.front().force.norm(),
              GetParam().tolerance_n + 1e-12);
  const scoring::TrialMetrics a = unmoved->Metrics(), b = after->Metrics();
  EXPECT_GT(a.path_length, 0);
  EXPECT_NEAR(b.score, a.score, 1e-6);
  EXPECT_NEAR(b.duration, a.duration, 1e-9);
  EXPECT_NEAR(b.path_length, a.path_length, 1e-9);
  EXPECT_NEAR(b.peak_force, a.peak_force, GetParam().tolerance_n + 1e-12);
  EXPECT_EQ(b.overload_events, a.overload_events);
  // The released and absorbed energies carry on from where they were.
  EXPECT_NEAR(got.back().released_j, expected.back().released_j, 1e-6);
}

INSTANTIATE_TEST_SUITE_P(
    EveryModel, StateTest,
    ::testing::Values(Case{"arm-torsion", 1e-9},                // coil spring, limb twist
                      Case{"arm-torsion-reduced", 1e-9},        // reduced twist
                      Case{"arm-torsion-reduced", 1e-9, true},  // relaxing
                      Case{"organ-surface-twist", 1e-9},        // surface twist (the jaws' grasp)
                      Case{"sphere-palpation-256", 1e-3},       // mass-spring, implicit
                      Case{"sphere-palpation-rings", 1e-9}),    // ring layer
    [](const ::testing::TestParamInfo<Case>& param) {
      std::string name = std::string(param.param.scene) + (param.param.relaxing ? "-relaxing" : "");
      for (char& c : name)
        if (c == '-') c = '_';
      return name;
    });

// Bytes that are not this scene's state: another scene's, another format's, cut short, or with
// a non-finite value. Each is refused with why, and the simulation answers as one just built.
TEST(StateRefusalTest, AnotherScenesOrABrokenStateIsRefusedAndChangesNothing) {
  auto arm = LoadSceneByName("arm-torsion");
  auto sphere = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(arm.ok() && sphere.ok());
  auto samples = ScriptedTrainee(*sphere, TraineeStyle::kGood);
  ASSERT_TRUE(samples.ok());
  samples->resize(std::min<size_t>(samples->size(), 1200));  // the approach and the press
  auto fresh = Make(*sphere);
  ASSERT_TRUE(fresh);
  const std::vector<ForceCommand> expected = Play(*fresh, *samples);

  auto other = Make(*arm);
  auto led = Make(*sphere);
  ASSERT_TRUE(other && led);
  const std::vector<StylusSample> part(samples->begin(), samples->begin() + samples->size() / 2);
  Play(*other, part);
  Play(*led, part);
  const std::string arms = other->SaveState(), spheres = led->SaveState();

  std::vector<std::pair<std::string, std::string>> bad = {
      {"another scene's", arms},
      {"empty", ""},
      {"not a state", std::string(64, 'x')},
  };
  std::string version = spheres;
  version[4] = static_cast<char>(version[4] + 1);
  bad.emplace_back("another format version", version);
  for (size_t len : {size_t{8}, size_t{40}, spheres.size() / 2, spheres.size() - 1})
    bad.emplace_back("cut to " + std::to_string(len) + " bytes", spheres.substr(0, len));
  bad.emplace_back("with a byte more", spheres + '\0');
  std::string nan_state = spheres;  // the last particle's velocity's z: a NaN
  const double nan = std::nan("");
  std::memcpy(nan_state.data() + nan_state.size() - sizeof nan, &nan, sizeof nan);
  bad.emplace_back("with a NaN", nan_state);

  for (const auto& [what, bytes] : bad) {
    auto sim = Make(*sphere);
    ASSERT_TRUE(sim);
    const Status s = sim->RestoreState(bytes);
    ASSERT_FALSE(s.ok()) << what << " was taken";
    EXPECT_EQ(s.error().code, ErrorCode::kFailedPrecondition) << what;
    EXPECT_NE(s.error().message.find("cannot take over a session of scene"), std::string::npos)
        << s.error().message;
    const std::vector<ForceCommand> got = Play(*sim, *samples);
    ASSERT_EQ(got.size(), expected.size());
    double worst = 0;
    for (size_t i = 0; i < got.size(); ++i)
      worst = std::max(worst, (got[i].force - expected[i].force).norm());
    EXPECT_EQ(worst, 0) << what << ": the refused state changed the simulation";
  }
  // And the state itself is taken.
  auto sim = Make(*sphere);
  ASSERT_TRUE(sim);
  EXPECT_TRUE(sim->RestoreState(spheres).ok());
}

}  // namespace
}  // namespace vsurg::sim
