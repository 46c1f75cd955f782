// The tissue's surface and contact law as a station holds them from its join: the surface at rest
// (positions, triangles), the contact's stiffness at each vertex and its damping, and the reach
// within which the surface ahead of a free tool is rendered. With it a station begins a contact
// where the surface is from its own tip, on the cycle the tip crosses it, however long the round
// trip (model-mediated teleoperation, Mitra & Niemeyer 2008: the remote environment's model at
// the operator's side; the server's answers then correct it). Without it, the surface ahead comes
// only in the server's answers about samples within the reach, a round trip late: at 150 ms each
// way a tool that covers the reach in less than 300 ms touched the tissue before the station knew
// of it.
//
// SurfaceContact renders it per servo cycle: the contact begins only when the tip crosses the
// surface from outside (the plane of the last outside cycle's nearest face is then held while the
// tip is in: a tip never jumps across a thin part to its far side), and ends when the tip is back
// out of that plane. A tip already inside when the surface takes over (the tissue still yields
// after a release, the surface at rest is above it) gets nothing from it until it has left: the
// server's answers describe the tissue there.
//
// Units: m, N/m, N·s/m. No allocation per cycle; any thread may query one TissueSurface (const).
#pragma once

#include <memory>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/bvh.h"
#include "common/geometry/mesh.h"
#include "common/haptics/types.h"
#include "common/haptics/viscoelastic.h"

namespace vsurg::haptics {

struct SurfaceSpec {
  std::vector<Vec3> positions;                // m, the surface at rest
  std::vector<geometry::Triangle> triangles;  // counter-clockwise from outside
  std::vector<double> stiffness;              // N/m per vertex: the contact's slope over depth
  double damping = 0;                         // N·s/m along the normal, as the server's proxy
  double reach = 0.03;                        // m: a free tip this near gets the surface ahead
  // The tissue under the proxy, where the scene knows it (the viscoelastic contact's k_t and b,
  // haptics/viscoelastic.h, calibrated by pressing the scene at the server): a contact from the
  // surface is then the proxy's spring in series with it, integrated over the station's own
  // depths, as the server's contact answers are rendered. 0: the proxy's spring alone.
  double tissue_stiffness = 0;  // N/m
  double tissue_damping = 0;    // N·s/m
  // Where the scene measured it, the tissue's static curve (count 0: none): the contact from the
  // surface then yields along it, not along k_t·S, which is the tangent at a press's depth and
  // no line through the rest surface (the 256-particle ball's curve is 19% above it at 4 mm).
  TissueCurve tissue_curve;
  // The tissue's contact loads the face's corners (a mass-spring surface's: the face tilts as
  // they yield, YieldedNormal); else it yields about the contact point and keeps its normal.
  bool corners_yield = false;
};

class TissueSurface {
 public:
  // Bounds on what a server may send (a hostile or broken one gets a refusal, not a station
  // that allocates or renders without bound).
  static constexpr size_t kMaxVertices = 200000, kMaxTriangles = 400000;
  static constexpr double kMaxStiffness = 1e5, kMaxDamping = 1e3, kMaxReach = 0.2;  // N/m, N·s/m, m

  static Expected<std::shared_ptr<const TissueSurface>> Create(SurfaceSpec spec);

  // The surface ahead of a free tip x (outside, within reach): a contact model of the nearest
  // face's plane, F = k·((p − x)·n)·n − c·(v·n)·n on the penetrating side only, k interpolated
  // from the face's vertices at the nearest point. False when nothing is within reach or x is
  // behind the nearest face. `start` is the caller's previous face (−1: none), updated; with
  // `barycentric`, the nearest point's weights on that face.
  bool Ahead(const Vec3& x, LocalModel& out, int& start, Vec3* barycentric = nullptr) const;

  // The normal of face `triangle` once the tissue has yielded `yield` (m) under the point of
  // barycentric weights w on it: each corner pushed in along the rest normal by w_i·yield/Σw_j².
  // That is the load spread over the corners by w, as the server's contact spreads it, each corner
  // yielding in proportion; its interpolation at the point is the yield. A press off a corner
  // tilts the face towards the corner that yields most. Unit.
  Vec3 YieldedNormal(int triangle, const Vec3& w, double yield) const;

  const SurfaceSpec& spec() const { return spec_; }

 private:
  explicit TissueSurface(SurfaceSpec spec);
  SurfaceSpec spec_;
  geometry::Bvh bvh_;
};

// One station's contact with a TissueSurface, servo cycle by servo cycle (device thread).
class SurfaceContact {
 public:
  // period_s: the servo period the contact's tissue is integrated over (one step per Render).
  explicit SurfaceContact(std::shared_ptr<const TissueSurface> surface, double period_s = 1e-3)
      : surface_(std::move(surface)), period_(period_s) {}

  // This cycle's force at tip x moving at v; false when the surface gives nothing here (no
  // surface, free beyond the reach, or a tip that is in without having crossed). Call every
  // cycle, also when the force comes from elsewhere, so that a crossing is seen.
  bool Render(const Vec3& x, const Vec3& v, Vec3& force);
  // The tip went where the surface does not describe the tissue (a server's contact or grasp):
  // the next contact from the surface begins only after the tip has been outside again.
  void Yield() { state_ = State::kUnknown; }
  bool in_contact() const { return state_ == State::kIn; }
  // The surface carries the tissue under the proxy (SurfaceSpec::tissue_stiffness > 0).
  bool has_tissue() const { return surface_ && surface_->spec().tissue_stiffness > 0; }

 private:
  enum class State { kUnknown, kOutside, kIn };
  Vec3 InContact(const Vec3& x, const Vec3& v);
  std::shared_ptr<const TissueSurface> surface_;
  double period_;
  ViscoelasticContact tissue_;  // the tissue under the proxy since the crossing
  State state_ = State::kUnknown;
  LocalModel plane_;  // the last outside cycle's surface ahead, held while in
  bool have_plane_ = false;
  int start_ = -1;
  int face_ = -1;                // plane_'s face
  Vec3 weights_ = Vec3::Zero();  // plane_.position0's barycentric weights on it
};

}  // namespace vsurg::haptics
