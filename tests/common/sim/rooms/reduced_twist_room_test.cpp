// The reduced twist room (common/sim/rooms/reduced_twist_room.h): the limb twisted by its
// precomputed twist field.
#include <cstdlib>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, TheReducedArmIsTwistedToTheTargetAndCachesItsField) {
  namespace fs = std::filesystem;
  const test::TempDir dir("arm_cache");
  setenv("VSURG_CACHE_DIR", dir.string().c_str(), 1);
  double peak = 0;
  const scoring::TrialMetrics good = Replay("arm-torsion-reduced", TraineeStyle::kGood, &peak);
  unsetenv("VSURG_CACHE_DIR");
  EXPECT_TRUE(fs::exists(dir / "arm-torsion-reduced-twist.vrm"));
  ASSERT_TRUE(good.completed);
  EXPECT_LT(good.task_error, 5 * M_PI / 180);
  EXPECT_LE(peak, 3.3 + 1e-9);
  EXPECT_GE(good.score, 8.0);
  EXPECT_EQ(good.overload_events, 0);
}

}  // namespace
}  // namespace vsurg::sim
