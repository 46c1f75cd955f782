// The types of the tissue-room contract (common/sim/tissue_room.h), shared by every room.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/geometry/mesh.h"
#include "common/sim/scene.h"
#include "common/tissue/coil_deformation.h"

namespace vsurg {
class StateWriter;
class StateReader;
}  // namespace vsurg

namespace vsurg::sim {

// What a room is built from: what Simulation::Create made of the scene.
struct RoomInputs {
  const Scene& scene;
  const geometry::TriMesh& rest;                  // the display surface at rest
  const std::vector<int>& held;                   // its vertices the scene's support holds
  const std::vector<geometry::Vec3>& centreline;  // limb meshes: the axis polyline; else empty
  std::string cache_dir;                          // reduced models' precomputation cache
  double mass = 0;                                // kg, the tissue's (density × volume)
  double proxy_stiffness = 0, proxy_damping = 0;  // N/m, N·s/m: the coupling to the tool
};

// What the haptic path asks of the deformation (published lock-free, latest wins).
struct DeformInput {
  uint64_t grasp_id = 0;  // changes at every new grasp
  bool grasping = false;
  int grasp_vertex = -1;  // surface twist: the rest surface vertex the jaws hold
  double torque = 0;      // N·m, twist scenes
  geometry::Vec3 grasp_point = geometry::Vec3::Zero();
  int triangle = -1;  // contact triangle, −1: no contact
  geometry::Vec3 barycentric = geometry::Vec3::Zero();
  geometry::Vec3 force_on_tissue = geometry::Vec3::Zero();  // N
  geometry::Vec3 hip = geometry::Vec3::Zero();              // m, the tip, while in contact
  uint64_t contact_id = 0;                                  // changes at every new contact
  // A second hand's grasper on a cut patch (rooms/cut_room.h): while `hold_stiffness` > 0, the
  // particle under `hold_at` (rest plane, m) is held toward `hold_target` (m) by a spring of that
  // stiffness (N/m; it fades to 0 when the hand lets go or its device goes silent).
  geometry::Vec3 hold_at = geometry::Vec3::Zero();
  geometry::Vec3 hold_target = geometry::Vec3::Zero();
  double hold_stiffness = 0;
  bool operator==(const DeformInput&) const = default;
  template <class A>
  void Persist(A& a) {  // common/core/state_archive.h
    a(grasp_id, grasping, grasp_vertex, torque, grasp_point, triangle, barycentric, force_on_tissue,
      hip, contact_id, hold_at, hold_target, hold_stiffness);
  }
};

// For a model that only a grasp deforms (the twist models): whether two inputs ask it for the
// same update, the grasp and its torque alike. A touch without a grasp changes the contact's
// fields, which such a model never reads, so it is not handed over.
inline bool SameGraspRequest(const DeformInput& a, const DeformInput& b) {
  return a.grasp_id == b.grasp_id && a.grasping == b.grasping && a.grasp_vertex == b.grasp_vertex &&
         a.torque == b.torque && a.grasp_point == b.grasp_point;
}

// A grasp asked for at the proxy (haptic thread).
struct GraspQuery {
  int triangle = -1;
  geometry::Vec3 barycentric = geometry::Vec3::Zero();
  geometry::Vec3 point = geometry::Vec3::Zero();  // m, the proxy on the surface
  geometry::Vec3 normal = geometry::Vec3::UnitZ();
  double min_lever = 0.03;  // m
  template <class A>
  void Persist(A& a) {  // common/core/state_archive.h
    a(triangle, barycentric, point, normal, min_lever);
  }
};

// The grasp's twist axis, the point it passes through, the lever the torque acts on, and (surface
// twist) the vertex the jaws hold.
struct GraspFrame {
  geometry::Vec3 axis = geometry::Vec3::UnitZ();
  geometry::Vec3 axis_point = geometry::Vec3::Zero();
  double lever = 0.03;  // m
  int grasp_vertex = -1;
};

struct TwistAnswer {
  double torque = 0;     // N·m
  double stiffness = 0;  // N·m/rad, dT/dΦ there (the station's local model); 0 past capacity
  bool overload = false;
  // N·m: the elastic torque the shape answers, where a relaxing tissue's held torque falls below
  // it (the grasp holds the twist, the deformation stays); NaN: the torque itself.
  double shape = std::numeric_limits<double>::quiet_NaN();
};

// The contact the local model is asked about (haptic thread).
struct ContactQuery {
  const geometry::Triangle& triangle;
  const geometry::Vec3& barycentric;
  const geometry::Vec3& rest_normal;
  double proxy_stiffness = 0;  // N/m
};

// A limb turned by the coil-spring model, in the numbers that make its whole surface: a viewer
// with the same scene binds the same deformer at the grasp's arc length along the centreline and
// turns it by the torque (tissue::CoilDeformer::CreateForLimb, Update), as the room did.
struct CoilTwistShape {
  uint64_t key = 0;    // CoilLimbKey of the room's model, mesh and centreline
  uint64_t grasp = 0;  // the grasp it is bound to (DeformInput::grasp_id)
  double arc = 0;      // m along the centreline
  double torque = 0;   // N·m
};

// What a viewer must share with a coil limb's room to remake its twist: the model's parameters,
// the rest surface (every vertex, in order) and the centreline, hashed (64-bit FNV-1a over their
// bytes). Equal keys: the same deformer; a viewer whose scene differs in any of them has another
// key and is sent vertices instead.
uint64_t CoilLimbKey(const tissue::CoilSpringParams& model, const std::vector<geometry::Vec3>& rest,
                     const std::vector<geometry::Vec3>& centreline);
// A scene's own: its CoilLimbKey when its tissue is the coil model in limb mode on a limb (a
// centreline), else 0 (no twist frames).
uint64_t CoilLimbKeyOf(const Scene& scene, const SceneMesh& mesh);

// One deformation update to publish. `positions` is the room's own (valid until its next Deform).
struct Deformed {
  // Null when the update's vertices are left to be made: then they are `turn`'s rest mesh turned
  // as `turn_state` says (tissue::CoilDeformer::TurnFromRest), for whoever needs them.
  const std::vector<geometry::Vec3>* positions = nullptr;
  bool overload = false;
  bool outside_model = false;  // the reduced contact used a neighbour's precomputed response
  std::optional<CoilTwistShape> twist;  // these positions as a coil limb's twist, when they are
  // A model whose topology changes (a cut): its faces now, as the rest mesh's triangles re-pointed
  // at the particles a cut made (a removed face is {0, 0, 0}), and how many times they changed.
  // Null for the others: their faces are the rest mesh's.
  const std::vector<geometry::Triangle>* faces = nullptr;
  uint64_t topology = 0;
  // Where a tool works the tissue now (m, the scene's frame; a cut's blade on the patch): the
  // frames send the vertices near it at the finest threshold (Simulation::TakeVisualFrame).
  std::optional<geometry::Vec3> focus = std::nullopt;
  std::shared_ptr<const tissue::CoilTurnTable> turn = nullptr;
  const tissue::CoilState* turn_state = nullptr;  // the room's own, as `positions`
};

}  // namespace vsurg::sim
