// Each tissue model in its own room (Box2D's joints: one type per model, its state in its own
// struct and file, one dispatch): what a Simulation asks of the model its scene names, and
// nothing of the haptics every model shares (safety, the proxy, the trial recorder), which stay
// in Simulation.
//
// The contract. A room R is built from its scene by `Expected<R> R::Build(const RoomInputs&)` and
// has, each only where the model has it (Simulation asks `if constexpr (requires …)`):
//
//   static constexpr bool kPaced    the deformation steps on the scene's clock (dynamic models);
//                                   else it updates only when the haptic path asks something new
//   haptic thread (never allocates, never blocks; reads only what is immutable or its own):
//     bool StartGrasp(const GraspQuery&, GraspFrame&)   grasp-and-twist: the axis, point and
//                                   lever of a grasp at the proxy (false: no grasp here)
//     TwistAnswer Twist(double twist)                   the torque the tissue answers a twist
//     static bool SameRequest(const DeformInput&, const DeformInput&)   whether two inputs ask
//                                   the same update of this model (the fields it reads are
//                                   equal); the deformation is woken only for a new one. Without
//                                   it every field counts
//     double ContactStiffness(const ContactQuery&)      the local model's stiffness in contact
//                                   (the proxy's spring in series with the tissue behind it)
//   deformation thread (its own thread, or the caller's StepDeformation):
//     std::optional<Deformed> Deform(const DeformInput&)   one update; nullopt: nothing new
//
// Adding a model is a new room: its file pair, a line in TissueRoom and one in BuildRoom.
//
// Units: SI (m, N, N·m, rad). Threads: as marked above; a room's haptic-side and deformation-side
// members are disjoint, and whatever both read is immutable after Build.
#pragma once

#include <variant>

#include "common/core/expected.h"
#include "common/sim/rooms/coil_room.h"
#include "common/sim/rooms/cut_room.h"
#include "common/sim/rooms/mass_spring_room.h"
#include "common/sim/rooms/reduced_contact_room.h"
#include "common/sim/rooms/reduced_twist_room.h"
#include "common/sim/rooms/ring_layer_room.h"
#include "common/sim/rooms/surface_twist_room.h"

namespace vsurg::sim {

using TissueRoom = std::variant<CoilRoom, MassSpringRoom, RingLayerRoom, ReducedContactRoom,
                                ReducedTwistRoom, SurfaceTwistRoom, CutRoom>;

// The room the scene's region names, built (the reduced models' precomputation from the cache,
// or computed and cached).
Expected<TissueRoom> BuildRoom(const RoomInputs& in);

}  // namespace vsurg::sim
