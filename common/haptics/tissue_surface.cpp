#include "common/haptics/tissue_surface.h"

#include <cmath>
#include <string>

namespace vsurg::haptics {

namespace {

bool Finite(const std::vector<Vec3>& v) {
  for (const Vec3& p : v)
    if (!p.allFinite()) return false;
  return true;
}

Status Check(const SurfaceSpec& s) {
  const size_t n = s.positions.size();
  if (n < 3 || n > TissueSurface::kMaxVertices)
    return InvalidArgument("surface", "the surface needs 3.." +
                                          std::to_string(TissueSurface::kMaxVertices) +
                                          " vertices, not " + std::to_string(n));
  if (s.triangles.empty() || s.triangles.size() > TissueSurface::kMaxTriangles)
    return InvalidArgument("surface", "the surface needs 1.." +
                                          std::to_string(TissueSurface::kMaxTriangles) +
                                          " triangles, not " + std::to_string(s.triangles.size()));
  if (s.stiffness.size() != n)
    return InvalidArgument("surface", "one contact stiffness per vertex is needed");
  if (!Finite(s.positions)) return InvalidArgument("surface", "a vertex is not finite");
  for (const geometry::Triangle& t : s.triangles)
    for (int i : t)
      if (i < 0 || static_cast<size_t>(i) >= n)
        return InvalidArgument("surface", "a triangle names a vertex the surface does not have");
  for (double k : s.stiffness)
    if (!(k >= 0 && k <= TissueSurface::kMaxStiffness))
      return InvalidArgument("surface", "a contact stiffness is outside 0..1e5 N/m");
  if (!(s.damping >= 0 && s.damping <= TissueSurface::kMaxDamping))
    return InvalidArgument("surface", "the contact damping is outside 0..1000 N·s/m");
  if (!(s.reach > 0 && s.reach <= TissueSurface::kMaxReach))
    return InvalidArgument("surface", "the reach is outside (0, 0.2] m");
  if (!(s.tissue_stiffness >= 0 && s.tissue_stiffness <= TissueSurface::kMaxStiffness) ||
      !(s.tissue_damping >= 0 && s.tissue_damping <= TissueSurface::kMaxDamping))
    return InvalidArgument("surface", "the tissue's stiffness or damping is out of bounds");
  if (s.tissue_curve.count != 0 && !s.tissue_curve.Valid())
    return InvalidArgument("surface",
                           "the tissue's curve must rise strictly from (0, 0) in 1..16 points");
  return Status::Ok();
}

double Depth(const LocalModel& plane, const Vec3& x) {
  return plane.normal.dot(plane.position0 - x);
}

}  // namespace

Expected<std::shared_ptr<const TissueSurface>> TissueSurface::Create(SurfaceSpec spec) {
  if (Status s = Check(spec); !s.ok()) return s.error();
  return std::shared_ptr<const TissueSurface>(new TissueSurface(std::move(spec)));
}

TissueSurface::TissueSurface(SurfaceSpec spec) : spec_(std::move(spec)) {
  geometry::TriMesh mesh;
  mesh.positions = spec_.positions;
  mesh.triangles = spec_.triangles;
  bvh_ = geometry::Bvh(mesh);
}

bool TissueSurface::Ahead(const Vec3& x, LocalModel& out, int& start, Vec3* barycentric) const {
  if (!x.allFinite()) return false;
  const geometry::ClosestHit c =
      bvh_.Closest(spec_.positions, x, spec_.reach, Vec3::Zero(), -2.0, start);
  start = c.triangle;
  if (c.triangle < 0) return false;
  const geometry::Triangle& tri = spec_.triangles[c.triangle];
  const Vec3 n = geometry::TriangleNormal(spec_.positions, tri);
  if (!n.allFinite() || (x - c.point).dot(n) < 0) return false;  // behind the face
  double k = 0;
  for (int i = 0; i < 3; ++i) k += c.barycentric[i] * spec_.stiffness[tri[i]];
  if (!(k >= 0)) return false;
  out = LocalModel{};
  out.kind = LocalModel::Kind::kContact;
  out.normal = n;
  out.position0 = c.point;
  out.jacobian = -k * n * n.transpose();
  out.contact_damping = spec_.damping;
  if (barycentric) *barycentric = c.barycentric;
  return true;
}

Vec3 TissueSurface::YieldedNormal(int triangle, const Vec3& w, double yield) const {
  const geometry::Triangle& tri = spec_.triangles[triangle];
  const Vec3 &a = spec_.positions[tri[0]], &b = spec_.positions[tri[1]],
             &c = spec_.positions[tri[2]];
  const Vec3 unit = (b - a).cross(c - a).normalized();
  if (!std::isfinite(yield) || !(w.squaredNorm() > 0)) return unit;
  const Vec3 sink = yield / w.squaredNorm() * w;  // each corner's yield, m
  const Vec3 t = ((b - sink[1] * unit) - (a - sink[0] * unit))
                     .cross((c - sink[2] * unit) - (a - sink[0] * unit))
                     .normalized();
  return t.allFinite() && t.dot(unit) > 0 ? t : unit;
}

// In contact through the held plane: the proxy's spring alone, or in series with the tissue
// (integrated one servo period a call); either with the proxy's damping, never pulling.
Vec3 SurfaceContact::InContact(const Vec3& x, const Vec3& v) {
  if (!(surface_->spec().tissue_stiffness > 0))
    return plane_.Render(x, Eigen::Quaterniond::Identity(), 0, v);
  const Vec3& n = plane_.normal;
  double fn = tissue_.Step(Depth(plane_, x), period_);
  if (v.allFinite()) fn -= plane_.contact_damping * v.dot(n);
  // Along the face as the tissue's yield has tilted it, where it does (the depth stays along n).
  const Vec3 along = surface_->spec().corners_yield
                         ? surface_->YieldedNormal(face_, weights_, tissue_.sigma())
                         : n;
  const Vec3 f = fn > 0 ? Vec3(fn * along) : Vec3::Zero();
  return f.allFinite() ? f : Vec3::Zero();
}

bool SurfaceContact::Render(const Vec3& x, const Vec3& v, Vec3& force) {
  force.setZero();
  if (!surface_ || !x.allFinite()) {
    state_ = State::kUnknown;
    return false;
  }
  if (state_ == State::kIn) {
    if (Depth(plane_, x) > 0) {
      force = InContact(x, v);
      return true;
    }
    state_ = State::kOutside;  // back out through the plane it went in by
  }
  LocalModel ahead;
  if (surface_->Ahead(x, ahead, start_, &weights_)) {
    state_ = State::kOutside;
    plane_ = ahead;
    face_ = start_;
    have_plane_ = true;
    return true;  // outside, within reach: nothing to feel yet
  }
  if (state_ == State::kOutside && have_plane_) {
    // Behind the nearest face (or out of reach) after an outside cycle: a crossing once the tip
    // is behind the plane it came to.
    if (Depth(plane_, x) > 0) {
      state_ = State::kIn;
      const double k = -plane_.normal.dot(plane_.jacobian * plane_.normal);
      const SurfaceSpec& spec = surface_->spec();
      tissue_.Begin(0, k, spec.tissue_stiffness, spec.tissue_damping, 0, &spec.tissue_curve);
      force = InContact(x, v);
    }
    return true;
  }
  state_ = State::kUnknown;
  have_plane_ = false;
  return false;
}

}  // namespace vsurg::haptics
