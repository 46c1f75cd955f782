#include "common/sim/tissue_room.h"

namespace vsurg::sim {

namespace {

template <class Room>
Expected<TissueRoom> Built(Expected<Room> room) {
  if (!room.ok()) return room.error();
  return TissueRoom(std::in_place_type<Room>, std::move(*room));
}

}  // namespace

Expected<TissueRoom> BuildRoom(const RoomInputs& in) {
  const RegionSpec& region = in.scene.region;
  switch (region.kind) {
    case ModelKind::kCoil:
      return Built(CoilRoom::Build(in));
    case ModelKind::kMassSpring:
      return Built(MassSpringRoom::Build(in));
    case ModelKind::kRingLayer:
      return Built(RingLayerRoom::Build(in));
    case ModelKind::kCutMembrane:
      return Built(CutRoom::Build(in));
    case ModelKind::kReduced:
      switch (region.reduced.mode) {
        case ReducedMode::kContact:
          return Built(ReducedContactRoom::Build(in));
        case ReducedMode::kTwist:
          return Built(ReducedTwistRoom::Build(in));
        case ReducedMode::kSurfaceTwist:
          return Built(SurfaceTwistRoom::Build(in));
      }
  }
  return InvalidArgument("regions[0].model", "no such tissue model");
}

}  // namespace vsurg::sim
