// A station's own copy of a coil limb's deformer (the coil-spring paper's model in limb mode):
// the surface the server twisted, remade from a SceneFrame's coil_twist. The station loads the
// same scene file as the server, so the same mesh (same vertex order), centreline and model bind
// the same deformer at the grasp's arc length and turn it by the torque to the same vertices: a
// frame of three numbers instead of every vertex of the limb (server/net/visual_sender.h).
//
// A new grasp binds anew (the vertices' projections onto the centreline are made once, at For;
// a binding sorts the limb's thousands of vertices by their distance from the grasp); a twist whose
// arc lies off the centreline, or that arrives for a scene without a coil limb, shapes nothing.
// Threads: the station's render thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/geometry/mesh.h"
#include "common/sim/scene.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"
#include "proto/wire/messages.h"

namespace vsurg::client {

class CoilTwistView {
 public:
  // For a scene whose tissue is the coil model in limb mode; nullopt for any other.
  static std::optional<CoilTwistView> For(const sim::Scene& scene, const sim::SceneMesh& mesh);

  // The whole surface for this twist, every vertex in mesh order (indices 0..n−1). False, and
  // nothing written, when the twist cannot be shaped here.
  bool Shape(const wire::CoilTwist& twist, std::vector<int32_t>& indices,
             std::vector<geometry::Vec3>& positions);

  // The limb's key (sim::CoilLimbKey), which the station declares in its stylus datagrams: the
  // server sends twists only when it is its own, and a twist of another key shapes nothing.
  uint64_t key() const { return key_; }

 private:
  CoilTwistView() = default;
  std::shared_ptr<const tissue::CoilSpringModel> model_;  // immutable (as the room holds it)
  std::vector<geometry::Vec3> rest_;
  std::vector<geometry::CentrelineProjection> projection_;  // each rest vertex's on the centreline
  double length_ = 0;                                       // the centreline's arc length, m
  uint64_t key_ = 0;
  // The deformer bound last, to this grasp at this arc length.
  std::unique_ptr<tissue::CoilDeformer> deformer_;
  uint64_t grasp_ = 0;
  double arc_ = 0;
};

}  // namespace vsurg::client
