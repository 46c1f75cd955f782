#include "common/geometry/visual_surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <utility>

#include <Eigen/LU>

#include "common/geometry/bvh.h"

namespace vsurg::geometry {

TriMesh PhongRefine(const TriMesh& coarse, int levels, double alpha) {
  TriMesh rest = coarse;
  if (rest.normals.size() != rest.positions.size()) ComputeVertexNormals(rest);
  // Each fine triangle lies in one coarse triangle (its host) and carries its corners'
  // barycentric weights there; a midpoint's weights are its edge ends' mean.
  struct Corner {
    int vertex;
    Vec3 b;
  };
  struct Fine {
    int host;
    std::array<Corner, 3> c;
  };
  std::vector<Fine> triangles;
  triangles.reserve(coarse.triangles.size());
  for (int t = 0; t < coarse.TriangleCount(); ++t) {
    const Triangle& tri = coarse.triangles[t];
    triangles.push_back({t,
                         {Corner{tri[0], Vec3::UnitX()}, Corner{tri[1], Vec3::UnitY()},
                          Corner{tri[2], Vec3::UnitZ()}}});
  }
  int vertices = coarse.VertexCount();
  std::vector<std::pair<int, Vec3>> placed(vertices);  // host triangle and weights per vertex
  for (int t = 0; t < coarse.TriangleCount(); ++t)
    for (int k = 0; k < 3; ++k) placed[coarse.triangles[t][k]] = {t, Vec3::Unit(k)};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoints;
    std::vector<Fine> next;
    next.reserve(4 * triangles.size());
    for (const Fine& f : triangles) {
      Corner m[3];
      for (int k = 0; k < 3; ++k) {
        const Corner &a = f.c[k], &b = f.c[(k + 1) % 3];
        const auto key = std::make_pair(std::min(a.vertex, b.vertex), std::max(a.vertex, b.vertex));
        auto [it, fresh] = midpoints.emplace(key, vertices);
        if (fresh) {
          ++vertices;
          placed.push_back({f.host, 0.5 * (a.b + b.b)});
        }
        m[k] = {it->second, 0.5 * (a.b + b.b)};
      }
      next.push_back({f.host, {f.c[0], m[0], m[2]}});
      next.push_back({f.host, {m[0], f.c[1], m[1]}});
      next.push_back({f.host, {m[2], m[1], f.c[2]}});
      next.push_back({f.host, {m[0], m[1], m[2]}});
    }
    triangles = std::move(next);
  }
  // Phong tessellation (Boubekeur & Alexa 2008): the linear point q projected onto each
  // corner's tangent plane, those projections blended with the same weights, and α of that
  // taken. It passes through the physics vertices and bulges as their normals say: a sphere's
  // coarse facets come out round, with the contact where the physics puts it.
  TriMesh out;
  out.positions.resize(vertices);
  for (int v = 0; v < vertices; ++v) {
    const Triangle& t = coarse.triangles[placed[v].first];
    const Vec3& b = placed[v].second;
    const Vec3 q =
        b[0] * rest.positions[t[0]] + b[1] * rest.positions[t[1]] + b[2] * rest.positions[t[2]];
    Vec3 phong = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      const Vec3 &p = rest.positions[t[k]], &n = rest.normals[t[k]];
      phong += b[k] * (q - (q - p).dot(n) * n);
    }
    out.positions[v] = (1 - alpha) * q + alpha * phong;
  }
  out.triangles.reserve(triangles.size());
  for (const Fine& f : triangles)
    out.triangles.push_back({f.c[0].vertex, f.c[1].vertex, f.c[2].vertex});
  ComputeVertexNormals(out);
  return out;
}

namespace {

double Bump(double x, double centre, double sigma) {
  const double u = (x - centre) / sigma;
  return std::exp(-0.5 * u * u);
}

// The shortest angle from b to a, in (−π, π].
double AngleBetween(double a, double b) {
  return std::remainder(a - b, 2 * std::numbers::pi);
}

}  // namespace

Expected<TriMesh> MakeLimbSkin(const LimbParams& p, int around, int along) {
  if (around < 8 || around > 4096) return InvalidArgument("around", "8..4096 vertices around");
  if (along < 4 || along > 8192) return InvalidArgument("along", "4..8192 rings along");
  auto limb = MakeLimb(p);
  if (!limb.ok()) return limb.error();
  const double length = p.length;
  // The radius at (z, θ): z from the elbow (0) to the wrist (length); θ from +x, the back of
  // the forearm (dorsal) toward +y, the ulnar side at θ = π. Offsets in metres, scaled by the
  // limb's own radius so a calf or a child's arm keeps the proportions.
  const auto radius = [&](double z, double th) {
    const double a = limb->RadiusAt(z), s = z / length;
    const double scale = a / 0.035;
    double r = a;
    // Muscle bellies: the flexor mass (volar, −y) and the extensors (dorsal, +y) over the
    // proximal half, fuller on the radial side (θ ≈ 0).
    const double belly = Bump(s, 0.3, 0.17);
    r += scale * 0.0030 * belly * (0.6 + 0.4 * std::cos(AngleBetween(th, -0.5)));
    // The olecranon: the bony point of the elbow, dorsal-ulnar.
    r += scale * 0.0035 * Bump(z, 0.010, 0.009) * Bump(AngleBetween(th, 2.2), 0, 0.35);
    // The wrist flattened front to back (dorsal and volar in, radial and ulnar out).
    const double wrist = std::clamp((s - 0.62) / 0.3, 0.0, 1.0);
    r *= 1 + 0.10 * wrist * std::cos(2 * (th - 0.5 * std::numbers::pi) + std::numbers::pi);
    // The ulnar styloid, and two volar tendons (palmaris longus, flexor carpi radialis).
    r += scale * 0.0022 * Bump(z, length - 0.013, 0.006) *
         Bump(AngleBetween(th, std::numbers::pi), 0, 0.28);
    const double tendons = Bump(AngleBetween(th, -0.5 * std::numbers::pi), 0, 0.06) +
                           0.8 * Bump(AngleBetween(th, -0.5 * std::numbers::pi + 0.45), 0, 0.06);
    r += scale * 0.0007 * wrist * tendons;
    // Both ends rounded in over the last 6 mm.
    constexpr double kRound = 0.006;
    const double end = std::min(z, length - z);
    if (end < kRound) {
      const double u = 1 - end / kRound;
      r -= kRound * (1 - std::sqrt(std::max(0.0, 1 - u * u))) * 0.8;
    }
    return r;
  };
  TriMesh skin;
  constexpr int kCapRings = 10;
  skin.positions.reserve(static_cast<size_t>(around) * (along + 2 * kCapRings) + 2);
  const auto angle = [&](int k) { return 2 * std::numbers::pi * k / around; };
  for (int j = 0; j < along; ++j) {
    const double z = length * j / (along - 1);
    for (int k = 0; k < around; ++k) {
      const double r = radius(z, angle(k));
      skin.positions.emplace_back(r * std::cos(angle(k)), r * std::sin(angle(k)), z);
    }
  }
  const auto v = [&](int j, int k) { return j * around + (k % around); };
  for (int j = 0; j + 1 < along; ++j)
    for (int k = 0; k < around; ++k) {
      skin.triangles.push_back({v(j, k), v(j, k + 1), v(j + 1, k)});
      skin.triangles.push_back({v(j, k + 1), v(j + 1, k + 1), v(j + 1, k)});
    }
  // The end faces: rings in toward a centre, domed out by 2 mm (the limb goes on beyond).
  // Rings are named by their first vertex.
  const auto at = [&](int base, int k) { return base + (k % around); };
  const auto cap = [&](int edge_base, double z0, double outward) {
    int previous = edge_base;
    for (int i = 1; i < kCapRings; ++i) {
      const double f = 1 - static_cast<double>(i) / kCapRings;
      const int base = static_cast<int>(skin.positions.size());
      for (int k = 0; k < around; ++k) {
        const double r = radius(z0, angle(k)) * f;
        skin.positions.emplace_back(r * std::cos(angle(k)), r * std::sin(angle(k)),
                                    z0 + outward * 0.002 * (1 - f * f));
      }
      for (int k = 0; k < around; ++k) {
        if (outward < 0) {  // the elbow end: outward is −z
          skin.triangles.push_back({at(previous, k), at(base, k), at(previous, k + 1)});
          skin.triangles.push_back({at(previous, k + 1), at(base, k), at(base, k + 1)});
        } else {
          skin.triangles.push_back({at(previous, k), at(previous, k + 1), at(base, k)});
          skin.triangles.push_back({at(previous, k + 1), at(base, k + 1), at(base, k)});
        }
      }
      previous = base;
    }
    const int centre = static_cast<int>(skin.positions.size());
    skin.positions.emplace_back(0, 0, z0 + outward * 0.002);
    for (int k = 0; k < around; ++k) {
      if (outward < 0)
        skin.triangles.push_back({centre, at(previous, k + 1), at(previous, k)});
      else
        skin.triangles.push_back({centre, at(previous, k), at(previous, k + 1)});
    }
  };
  cap(0, 0.0, -1.0);
  cap((along - 1) * around, length, 1.0);
  ComputeVertexNormals(skin);
  return skin;
}

namespace {

// Solves p = x(b) + d·n(b) on triangle t (x, n interpolated linearly with b, n not normalised)
// for the weights b and the offset d by Newton's method from `b`; true when it converged.
bool SolveNormalProjection(const std::vector<Vec3>& x, const std::vector<Vec3>& n,
                           const Triangle& t, const Vec3& p, Vec3& b, double& d) {
  const Vec3 dx1 = x[t[1]] - x[t[0]], dx2 = x[t[2]] - x[t[0]];
  const Vec3 dn1 = n[t[1]] - n[t[0]], dn2 = n[t[2]] - n[t[0]];
  const auto at = [&](const Vec3& w, const std::vector<Vec3>& v) {
    return Vec3(w[0] * v[t[0]] + w[1] * v[t[1]] + w[2] * v[t[2]]);
  };
  {
    const Vec3 nb = at(b, n);
    d = nb.squaredNorm() > 0 ? (p - at(b, x)).dot(nb) / nb.squaredNorm() : 0;
  }
  for (int iteration = 0; iteration < 12; ++iteration) {
    const Vec3 residual = at(b, x) + d * at(b, n) - p;
    if (residual.norm() < 1e-10) return true;
    Eigen::Matrix3d jacobian;
    jacobian << dx1 + d * dn1, dx2 + d * dn2, at(b, n);
    const Vec3 step = jacobian.fullPivLu().solve(-residual);
    if (!step.allFinite()) return false;
    b[1] += step[0];
    b[2] += step[1];
    b[0] = 1 - b[1] - b[2];
    d += step[2];
    if (!b.allFinite() || b.cwiseAbs().maxCoeff() > 10) return false;  // far off this triangle
  }
  return (at(b, x) + d * at(b, n) - p).norm() < 1e-9;
}

}  // namespace

SurfaceMapping SurfaceMapping::Build(const TriMesh& coarse, const std::vector<Vec3>& fine_rest) {
  TriMesh rest = coarse;
  if (rest.normals.size() != rest.positions.size()) ComputeVertexNormals(rest);
  const Bvh bvh(rest);
  // Each triangle's neighbour across the edge opposite each corner (−1 on a boundary).
  std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> edge_users;
  for (int t = 0; t < rest.TriangleCount(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = rest.triangles[t][(k + 1) % 3], b = rest.triangles[t][(k + 2) % 3];
      edge_users[{std::min(a, b), std::max(a, b)}].push_back({t, k});
    }
  std::vector<std::array<int, 3>> across(rest.triangles.size(), {-1, -1, -1});
  for (const auto& [edge, users] : edge_users)
    if (users.size() == 2) {
      across[users[0].first][users[0].second] = users[1].first;
      across[users[1].first][users[1].second] = users[0].first;
    }
  SurfaceMapping m;
  m.anchors_.reserve(fine_rest.size());
  for (const Vec3& p : fine_rest) {
    const ClosestHit hit = bvh.Closest(rest.positions, p);
    Anchor anchor;
    if (hit.triangle < 0) {  // an empty physics surface: nothing to carry it
      m.anchors_.push_back(anchor);
      continue;
    }
    // First the point-normal projection: the triangle and weights whose interpolated normal
    // line passes through p, walking from the closest triangle toward the weight that is
    // negative. Only an offset along the normal then: nothing turns with a sheared face.
    const int start = hit.triangle;
    int t = start;
    Vec3 b = hit.barycentric;
    double d = 0;
    bool found = false;
    for (int walk = 0; walk < 16 && t >= 0; ++walk) {
      if (!SolveNormalProjection(rest.positions, rest.normals, rest.triangles[t], p, b, d)) break;
      Eigen::Index worst = 0;
      if (b.minCoeff(&worst) >= -1e-6) {
        found = true;
        break;
      }
      t = across[t][worst];
      b = Vec3::Constant(1.0 / 3);
    }
    if (found) {
      anchor.triangle = rest.triangles[t];
      anchor.b0 = static_cast<float>(b[0]);
      anchor.b1 = static_cast<float>(b[1]);
      anchor.d = static_cast<float>(d);
      m.max_normal_ = std::max(m.max_normal_, std::abs(d));
      m.anchors_.push_back(anchor);
      continue;
    }
    // Otherwise (a sharp rim or a fold): the closest point, with the rest of the offset in its
    // face's frame.
    const Triangle& tri = rest.triangles[start];
    const Vec3 &a = rest.positions[tri[0]], &bb = rest.positions[tri[1]],
               &c = rest.positions[tri[2]];
    const Vec3 e1 = (bb - a).normalized(), nf = (bb - a).cross(c - a).normalized();
    const Vec3 e2 = nf.cross(e1);
    Vec3 n = hit.barycentric[0] * rest.normals[tri[0]] + hit.barycentric[1] * rest.normals[tri[1]] +
             hit.barycentric[2] * rest.normals[tri[2]];
    if (n.norm() < 1e-6) n = nf;
    Eigen::Matrix3d frame;
    frame << e1, e2, n;
    const Vec3 offset = frame.fullPivLu().solve(p - hit.point);
    anchor.triangle = tri;
    anchor.b0 = static_cast<float>(hit.barycentric[0]);
    anchor.b1 = static_cast<float>(hit.barycentric[1]);
    anchor.t1 = static_cast<float>(offset[0]);
    anchor.t2 = static_cast<float>(offset[1]);
    anchor.d = static_cast<float>(offset[2]);
    m.max_tangential_ = std::max({m.max_tangential_, std::abs(offset[0]), std::abs(offset[1])});
    m.max_normal_ = std::max(m.max_normal_, std::abs(offset[2]));
    ++m.fallbacks_;
    m.anchors_.push_back(anchor);
  }
  return m;
}

void SurfaceMapping::Apply(const std::vector<Vec3>& coarse_positions,
                           const std::vector<Vec3>& coarse_normals,
                           std::vector<Eigen::Vector3f>& fine) const {
  fine.resize(anchors_.size(), Eigen::Vector3f::Zero());
  const size_t n = std::min(coarse_positions.size(), coarse_normals.size());
  for (size_t i = 0; i < anchors_.size(); ++i) {
    const Anchor& an = anchors_[i];
    const Triangle& t = an.triangle;
    if (static_cast<size_t>(std::max({t[0], t[1], t[2]})) >= n) continue;
    const Vec3 &a = coarse_positions[t[0]], &b = coarse_positions[t[1]],
               &c = coarse_positions[t[2]];
    const double b0 = an.b0, b1 = an.b1, b2 = 1.0 - b0 - b1;
    const Vec3 ab = b - a, nf_raw = ab.cross(c - a);
    const double lab = ab.norm(), lnf = nf_raw.norm();
    if (!(lab > 0) || !(lnf > 0)) continue;  // degenerate or non-finite: keep the last value
    const Vec3 e1 = ab / lab, nf = nf_raw / lnf, e2 = nf.cross(e1);
    const Vec3 nn =
        b0 * coarse_normals[t[0]] + b1 * coarse_normals[t[1]] + b2 * coarse_normals[t[2]];
    Vec3 p = b0 * a + b1 * b + b2 * c + an.d * nn;
    if (an.t1 != 0 || an.t2 != 0) p += an.t1 * e1 + an.t2 * e2;
    if (p.allFinite()) fine[i] = p.cast<float>();
  }
}

void VertexNormals(const std::vector<Triangle>& triangles,
                   const std::vector<Eigen::Vector3f>& positions,
                   std::vector<Eigen::Vector3f>& normals, const Eigen::Vector3f& fallback) {
  normals.assign(positions.size(), Eigen::Vector3f::Zero());
  for (const Triangle& t : triangles) {
    const Eigen::Vector3f n =
        (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
    normals[t[0]] += n;
    normals[t[1]] += n;
    normals[t[2]] += n;
  }
  for (Eigen::Vector3f& n : normals) {
    const float l = n.norm();
    n = l > 0 ? Eigen::Vector3f(n / l) : fallback;
  }
}

}  // namespace vsurg::geometry
