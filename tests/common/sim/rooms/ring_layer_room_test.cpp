// The ring-layer room (common/sim/rooms/ring_layer_room.h): the sphere pressed through its rings.
#include <gtest/gtest.h>

#include "tests/common/sim/rooms/room_test_support.h"

namespace vsurg::sim {
namespace {

using rooms_test::ExpectPalpatedByScriptedTrainees;
using rooms_test::Replay;

TEST(RoomTest, ScriptedTraineesPalpateTheRingLayerSphere) {
  ExpectPalpatedByScriptedTrainees("sphere-palpation-rings");
}

}  // namespace
}  // namespace vsurg::sim
