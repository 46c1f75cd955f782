// The cuttable patch's room (tissue/cut_membrane.h; common/sim/tissue_room.h has the contract):
// pattern cutting. The haptic path runs the blade (haptics/blade.h) and hands each piece its
// crack grows by to this room through a lock-free queue; the deformation carves it into the patch
// (node snapping: a cut edge costs a constant, a few µs), loads the patch with the blade's force
// at its tip, steps it at 1 ms, tears what a pull stretched past the failure strain, and
// publishes its particles and, when a cut changed them, its faces. The patch's particles are the
// rest mesh's vertices of the same index (MembraneSurface: the lattice, then the room cuts may
// fill), so the haptic path, the view and a station's mesh all count vertices alike.
//
// The blade's contact in DeformInput: `triangle` ≥ 0 while the blade loads the patch, `hip` its
// tip (m), `force_on_tissue` its force on the patch (N). The second hand's grasper: `hold_*`.
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/rooms/room_types.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::sim {

// A piece of the blade's crack, in the patch's plane (m).
struct CutSegment {
  double ax = 0, ay = 0, bx = 0, by = 0;
};

class CutRoom {
 public:
  static constexpr bool kPaced = true;  // steps at the scene's dt
  static constexpr int kQueue = 1024;   // crack pieces in flight from the haptic path
  static Expected<CutRoom> Build(const RoomInputs& in);
  CutRoom(CutRoom&&) noexcept;
  CutRoom& operator=(CutRoom&&) noexcept;
  ~CutRoom();

  // Haptic thread. PushCut: false when the queue is full (the deformation is kQueue pieces
  // behind): the caller offers the piece again later, so no piece of the crack is lost.
  bool PushCut(const CutSegment& s);
  // m and pieces, as the deformation last left them.
  double TornLength() const;
  int FreedPieces() const;
  // N, the patch's pull on the second hand's jaws as the deformation last left it (zero while
  // nothing is held). Its components are stored one by one: a reader may mix two steps' (1 ms).
  geometry::Vec3 HoldForce() const;
  // Set-up only (Simulation::Build, before the deformation runs): the patch, whose stiffnesses
  // the blade meets.
  const tissue::CutMembrane& patch() const { return *patch_; }

  // Deformation thread: the queued cuts, the blade's load, one step of dt, the tears.
  std::optional<Deformed> Deform(const DeformInput& in);
  // Live migration: a cut patch is not carried (its topology would have to be); Load refuses, so
  // a draining node keeps its cut sessions until they end.
  bool Load(StateReader& r);

 private:
  CutRoom() = default;
  void CopyOut(bool faces);  // the patch's particles and faces into the room's fixed-size arrays
  void Hold(const DeformInput& in);  // the second hand's jaws, before the step

  struct Shared;  // the queue and the counters both threads touch
  std::unique_ptr<Shared> shared_;
  // Deformation thread only.
  std::unique_ptr<tissue::CutMembrane> patch_;
  std::vector<geometry::Vec3> positions_;  // the rest mesh's size: particles, then spare room
  std::vector<geometry::Triangle> faces_;
  uint64_t topology_ = 0;
  int cut_edges_ = 0, freed_ = 0, torn_ = 0;
  double dt_ = 1e-3, spare_ = 0;  // s; m around the blade a pull does not tear (its own front)
  double edge_ = 0;               // m, the lattice's (immutable after Build)
};

}  // namespace vsurg::sim
