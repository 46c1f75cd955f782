#include "common/geometry/mesh_generators.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <unordered_map>

namespace vsurg::geometry {
namespace {

constexpr int kMaxSphereLevels = 8;  // 262146 vertices from an octahedron: far past any scene

TriMesh BaseOctahedron() {
  TriMesh m;
  m.positions = {Vec3(1, 0, 0),  Vec3(-1, 0, 0), Vec3(0, 1, 0),
                 Vec3(0, -1, 0), Vec3(0, 0, 1),  Vec3(0, 0, -1)};
  m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                 {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return m;
}

TriMesh BaseIcosahedron() {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriMesh m;
  m.positions = {Vec3(-1, t, 0), Vec3(1, t, 0), Vec3(-1, -t, 0), Vec3(1, -t, 0),
                 Vec3(0, -1, t), Vec3(0, 1, t), Vec3(0, -1, -t), Vec3(0, 1, -t),
                 Vec3(t, 0, -1), Vec3(t, 0, 1), Vec3(-t, 0, -1), Vec3(-t, 0, 1)};
  for (Vec3& p : m.positions) p.normalize();
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  return m;
}

// One level of 1→4 subdivision on the unit sphere; midpoints shared through an edge map.
void SubdivideOnUnitSphere(TriMesh& m) {
  std::unordered_map<uint64_t, int> midpoint;
  midpoint.reserve(m.triangles.size() * 2);
  auto mid = [&](int a, int b) {
    const uint64_t key = (static_cast<uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
    auto [it, inserted] = midpoint.try_emplace(key, m.VertexCount());
    if (inserted) m.positions.push_back((m.positions[a] + m.positions[b]).normalized());
    return it->second;
  };
  std::vector<Triangle> out;
  out.reserve(m.triangles.size() * 4);
  for (const Triangle& t : m.triangles) {
    const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
    out.push_back({t[0], ab, ca});
    out.push_back({ab, t[1], bc});
    out.push_back({ca, bc, t[2]});
    out.push_back({ab, bc, ca});
  }
  m.triangles = std::move(out);
}

}  // namespace

int SphereVertexCount(SphereBase base, int levels) {
  const int f0 = base == SphereBase::kOctahedron ? 8 : 20;
  // Closed genus-0 triangle mesh: V = F/2 + 2, and F = f0·4^L.
  return f0 * (1 << (2 * levels)) / 2 + 2;
}

int SphereLevelsForVertexCount(SphereBase base, int target_vertices) {
  int best = 0;
  for (int l = 1; l <= kMaxSphereLevels; ++l) {
    if (std::abs(SphereVertexCount(base, l) - target_vertices) <
        std::abs(SphereVertexCount(base, best) - target_vertices)) {
      best = l;
    }
  }
  return best;
}

Expected<TriMesh> MakeSubdividedSphere(const SphereParams& params) {
  if (!(params.radius > 0) || !std::isfinite(params.radius)) {
    return InvalidArgument("radius", "sphere radius must be a positive finite length in m");
  }
  if (params.levels < 0 || params.levels > kMaxSphereLevels) {
    return InvalidArgument("levels",
                           "subdivision levels must be in 0.." + std::to_string(kMaxSphereLevels));
  }
  if (!params.centre.allFinite()) return InvalidArgument("centre", "sphere centre must be finite");
  TriMesh m = params.base == SphereBase::kOctahedron ? BaseOctahedron() : BaseIcosahedron();
  for (int l = 0; l < params.levels; ++l) SubdivideOnUnitSphere(m);
  for (Vec3& p : m.positions) p = params.centre + params.radius * p;
  ComputeVertexNormals(m);
  return m;
}

LimbParams ForearmPreset() {
  return LimbParams{};
}

LimbParams CalfPreset() {
  LimbParams p;
  p.length = 0.36;
  p.radius_proximal = 0.055;
  p.radius_distal = 0.035;
  p.segments_around = 64;
  p.rings_along = 96;
  return p;
}

LimbParams WithResolution(LimbParams params, int target_vertices) {
  const double scale =
      std::sqrt(std::max(8.0, static_cast<double>(target_vertices - 2)) /
                (static_cast<double>(params.segments_around) * params.rings_along));
  params.segments_around =
      std::max(3, static_cast<int>(std::lround(params.segments_around * scale)));
  params.rings_along = std::max(2, static_cast<int>(std::lround(params.rings_along * scale)));
  return params;
}

double Limb::RadiusAt(double z) const {
  const double u = std::clamp(z / params.length, 0.0, 1.0);
  return params.radius_proximal + u * (params.radius_distal - params.radius_proximal);
}

Expected<Limb> MakeLimb(const LimbParams& p) {
  auto positive = [](double x) { return x > 0 && std::isfinite(x); };
  if (!positive(p.length)) return InvalidArgument("length", "limb length must be > 0 m");
  if (!positive(p.radius_proximal)) {
    return InvalidArgument("radius_proximal", "proximal radius must be > 0 m");
  }
  if (!positive(p.radius_distal)) {
    return InvalidArgument("radius_distal", "distal radius must be > 0 m");
  }
  if (p.segments_around < 3 || p.segments_around > 4096) {
    return InvalidArgument("segments_around", "segments around must be in 3..4096");
  }
  if (p.rings_along < 2 || p.rings_along > 8192) {
    return InvalidArgument("rings_along", "rings along must be in 2..8192");
  }
  Limb limb;
  limb.params = p;
  const int n = p.segments_around, m = p.rings_along;
  TriMesh& s = limb.surface;
  s.positions.reserve(static_cast<size_t>(n) * m + 2);
  limb.centreline.reserve(m);
  for (int j = 0; j < m; ++j) {
    const double z = p.length * j / (m - 1);
    const double a = limb.RadiusAt(z);
    limb.centreline.emplace_back(0, 0, z);
    for (int k = 0; k < n; ++k) {
      const double th = 2.0 * std::numbers::pi * k / n;
      s.positions.emplace_back(a * std::cos(th), a * std::sin(th), z);
    }
  }
  const int c0 = n * m, c1 = n * m + 1;
  s.positions.emplace_back(0, 0, 0);
  s.positions.emplace_back(0, 0, p.length);
  auto v = [n](int j, int k) { return j * n + (k % n); };
  s.triangles.reserve(2 * static_cast<size_t>(n) * m);
  for (int j = 0; j + 1 < m; ++j) {
    for (int k = 0; k < n; ++k) {
      s.triangles.push_back({v(j, k), v(j, k + 1), v(j + 1, k)});
      s.triangles.push_back({v(j, k + 1), v(j + 1, k + 1), v(j + 1, k)});
    }
  }
  for (int k = 0; k < n; ++k) {
    s.triangles.push_back({c0, v(0, k + 1), v(0, k)});
    s.triangles.push_back({c1, v(m - 1, k), v(m - 1, k + 1)});
  }
  ComputeVertexNormals(s);
  return limb;
}

}  // namespace vsurg::geometry
