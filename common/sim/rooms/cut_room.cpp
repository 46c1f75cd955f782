#include "common/sim/rooms/cut_room.h"

#include <array>

#include <boost/lockfree/spsc_queue.hpp>

#include "common/core/state_archive.h"
#include "common/sim/cut_drill.h"

namespace vsurg::sim {

struct CutRoom::Shared {
  boost::lockfree::spsc_queue<CutSegment, boost::lockfree::capacity<kQueue>> queue;
  std::atomic<int> torn{0}, freed{0};
  std::array<std::atomic<double>, 3> hold{};  // N, the pull on the jaws
};

CutRoom::CutRoom(CutRoom&&) noexcept = default;
CutRoom& CutRoom::operator=(CutRoom&&) noexcept = default;
CutRoom::~CutRoom() = default;

Expected<CutRoom> CutRoom::Build(const RoomInputs& in) {
  if (!in.scene.cut || in.scene.mesh.kind != MeshKind::kMembrane)
    return InvalidArgument("regions[0].model.type",
                           "regions[0].model.type: the cut-membrane model needs a cut scene");
  auto patch = tissue::CutMembrane::Create(in.scene.mesh.membrane);
  if (!patch.ok()) return patch.error();
  if (static_cast<size_t>(patch->ParticleRoom()) != in.rest.positions.size() ||
      static_cast<size_t>(patch->FaceCount()) != in.rest.triangles.size())
    return InvalidArgument("mesh", "mesh: not the cut's membrane");
  CutRoom room;
  room.patch_ = std::make_unique<tissue::CutMembrane>(std::move(*patch));
  room.shared_ = std::make_unique<Shared>();
  room.positions_ = in.rest.positions;
  room.faces_ = in.rest.triangles;
  room.dt_ = in.scene.region.dt;
  room.edge_ = room.patch_->EdgeLength();
  // The blade's own front: its reach (the stretch at the cutting force, the slit's half width)
  // and two edges, where the lattice's point-load strain is not the tissue's.
  auto blade = BladeOnPatch(in.scene.cut->blade, *room.patch_);
  if (!blade.ok()) return blade.error();
  room.spare_ = blade->Reach() + 2 * room.edge_;
  return room;
}

bool CutRoom::PushCut(const CutSegment& s) {
  return shared_->queue.push(s);
}

double CutRoom::TornLength() const {
  return shared_->torn.load(std::memory_order_relaxed) * edge_;
}

int CutRoom::FreedPieces() const {
  return shared_->freed.load(std::memory_order_relaxed);
}

geometry::Vec3 CutRoom::HoldForce() const {
  const auto& h = shared_->hold;
  return {h[0].load(std::memory_order_relaxed), h[1].load(std::memory_order_relaxed),
          h[2].load(std::memory_order_relaxed)};
}

// The jaws' spring at its (faded) stiffness, or none; a hold at the same point keeps its particle.
void CutRoom::Hold(const DeformInput& in) {
  if (in.hold_stiffness > 0)
    patch_->Hold({in.hold_at.x(), in.hold_at.y()}, in.hold_target, in.hold_stiffness);
  else
    patch_->Release();
}

std::optional<Deformed> CutRoom::Deform(const DeformInput& in) {
  const int edges_before = cut_edges_, freed_before = patch_->freed_pieces();
  shared_->queue.consume_all([&](const CutSegment& s) {
    cut_edges_ += patch_->Cut({s.ax, s.ay}, {s.bx, s.by});
  });
  const tissue::Vec2 tip(in.hip.x(), in.hip.y());
  patch_->Load(tip, in.triangle >= 0 ? in.force_on_tissue : geometry::Vec3::Zero());
  Hold(in);
  if (!patch_->Step(dt_)) {  // back at rest, unloaded and let go
    patch_->Load(tip, geometry::Vec3::Zero());
    patch_->Release();
  }
  const geometry::Vec3 pull = patch_->HoldForce();
  for (int k = 0; k < 3; ++k) shared_->hold[k].store(pull[k], std::memory_order_relaxed);
  const int tore = patch_->Tear(in.triangle >= 0 ? tip : tissue::Vec2::Constant(1e9), spare_);
  torn_ += tore;
  shared_->torn.store(torn_, std::memory_order_relaxed);
  shared_->freed.store(patch_->freed_pieces(), std::memory_order_relaxed);
  const bool topology =
      cut_edges_ != edges_before || tore > 0 || patch_->freed_pieces() != freed_before;
  if (topology) ++topology_;
  CopyOut(topology);
  Deformed d{&positions_, false, false, std::nullopt, &faces_, topology_};
  if (in.triangle >= 0) d.focus = in.hip;  // the blade on the patch
  return d;
}

// The patch's particles over the rest mesh's first vertices (the spare room stays where it is),
// and, after a topology change, its faces (a removed face collapsed to vertex 0).
void CutRoom::CopyOut(bool faces) {
  const auto& x = patch_->positions();
  std::copy(x.begin(), x.end(), positions_.begin());
  if (!faces) return;
  for (int f = 0; f < patch_->FaceCount(); ++f) {
    const auto v = patch_->face(f).v;
    faces_[static_cast<size_t>(f)] =
        patch_->Removed(f) ? geometry::Triangle{0, 0, 0} : geometry::Triangle{v[0], v[1], v[2]};
  }
}

bool CutRoom::Load(StateReader&) {
  return false;  // a cut patch's topology is not carried: the session stays where it is
}

}  // namespace vsurg::sim
