// The mass-spring room (common/sim/rooms/mass_spring_room.h): the 256-particle sphere pressed.
#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, ScriptedTraineesPalpateTheMassSpringSphere) {
  ExpectPalpatedByScriptedTrainees("sphere-palpation-256");
}

}  // namespace
}  // namespace vsurg::sim
