#include "common/geometry/tet_generators.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vsurg::geometry {
namespace {

// Positive orientation: swap two vertices when the signed volume is negative.
void AddOriented(TetMesh& m, int a, int b, int c, int d) {
  const Vec3& p = m.positions[a];
  const double v = (m.positions[b] - p).cross(m.positions[c] - p).dot(m.positions[d] - p);
  if (v < 0) std::swap(c, d);
  m.tetrahedra.push_back({a, b, c, d});
}

// Prism (bottom a, b, c; top = bottom + offset) into three tetrahedra; diagonal of every quad
// face from its lower-numbered bottom vertex to its higher-numbered top vertex.
void SplitPrism(TetMesh& m, int a, int b, int c, int offset) {
  std::array<int, 3> s = {a, b, c};
  std::sort(s.begin(), s.end());
  const int A = s[0] + offset, B = s[1] + offset, C = s[2] + offset;
  AddOriented(m, s[0], s[1], s[2], C);
  AddOriented(m, s[0], s[1], B, C);
  AddOriented(m, s[0], A, B, C);
}

}  // namespace

Expected<TetCylinder> MakeTetCylinder(const TetCylinderParams& p) {
  if (!(p.length > 0) || !std::isfinite(p.length))
    return InvalidArgument("length", "must be > 0 m");
  if (!(p.radius_base > 0) || !(p.radius_tip > 0) || !std::isfinite(p.radius_base) ||
      !std::isfinite(p.radius_tip))
    return InvalidArgument("radius", "radii must be > 0 m");
  if (p.rings < 1 || p.rings > 64) return InvalidArgument("rings", "must be within 1..64");
  if (p.layers < 1 || p.layers > 4096) return InvalidArgument("layers", "must be within 1..4096");

  // The cross-section: unit disc, centre + rings of 6k points, triangles between rings.
  std::vector<Eigen::Vector2d> disc = {Eigen::Vector2d::Zero()};
  std::vector<int> ring_start = {0};
  std::vector<std::array<int, 3>> tris;
  for (int k = 1; k <= p.rings; ++k) {
    ring_start.push_back(static_cast<int>(disc.size()));
    const int n = 6 * k;
    const double r = static_cast<double>(k) / p.rings;
    for (int i = 0; i < n; ++i) {
      const double t = 2.0 * std::numbers::pi * i / n;
      disc.emplace_back(r * std::cos(t), r * std::sin(t));
    }
  }
  for (int i = 0; i < 6; ++i) tris.push_back({0, 1 + i, 1 + (i + 1) % 6});
  for (int k = 2; k <= p.rings; ++k) {
    // Merge the inner ring (6(k−1) points) and the outer (6k) by angle.
    const int ni = 6 * (k - 1), no = 6 * k, si = ring_start[k - 1], so = ring_start[k];
    int i = 0, o = 0;
    while (i < ni || o < no) {
      const double ti = 2.0 * std::numbers::pi * (i + 1) / ni;  // angle of the next inner
      const double to = 2.0 * std::numbers::pi * (o + 1) / no;  // angle of the next outer
      const int ci = si + i % ni, co = so + o % no;
      if (o < no && (i >= ni || to <= ti + 1e-12)) {
        tris.push_back({ci, co, so + (o + 1) % no});
        ++o;
      } else {
        tris.push_back({ci, co, si + (i + 1) % ni});
        ++i;
      }
    }
  }

  TetCylinder out;
  out.params = p;
  const int per_layer = static_cast<int>(disc.size());
  for (int l = 0; l <= p.layers; ++l) {
    const double z = p.length * l / p.layers;
    const double a = p.radius_base + (p.radius_tip - p.radius_base) * z / p.length;
    for (const auto& q : disc) out.mesh.positions.emplace_back(a * q.x(), a * q.y(), z);
  }
  for (int l = 0; l < p.layers; ++l)
    for (const auto& t : tris)
      SplitPrism(out.mesh, l * per_layer + t[0], l * per_layer + t[1], l * per_layer + t[2],
                 per_layer);
  out.tip_area.assign(per_layer, 0.0);
  for (int v = 0; v < per_layer; ++v) {
    out.base.push_back(v);
    out.tip.push_back(p.layers * per_layer + v);
  }
  for (const auto& t : tris) {
    const auto& a = disc[t[0]];
    const auto& b = disc[t[1]];
    const auto& c = disc[t[2]];
    const double area = 0.5 * std::abs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x()) *
                        p.radius_tip * p.radius_tip;
    for (int v : t) out.tip_area[v] += area / 3.0;
  }
  if (Status s = Validate(out.mesh, 0.0); !s.ok()) return s.error();
  return out;
}

namespace {

// A grid of nx × ny × nz cubes, vertex (i, j, k) placed by `place`, every cube split into six
// tetrahedra (Kuhn) mirrored by index parity (the comment at MakeTetBall).
template <class Place>
Expected<TetMesh> KuhnGrid(int nx, int ny, int nz, const Place& place, bool mirror = true) {
  TetMesh mesh;
  auto id = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) mesh.positions.push_back(place(i, j, k));
  // Kuhn: six tetrahedra along a main diagonal of each cube, one per order of the three axes.
  // The cube is mirrored along every axis on which its index is odd, so neighbours are mirror
  // images across their shared face (which therefore is cut the same way from both sides) and
  // the diagonals alternate: one fixed diagonal everywhere makes the mesh anisotropic (a
  // vertical press on the pole then moves it sideways along the diagonal by a fifth as much).
  static const int kPaths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                   {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const int base[3] = {i, j, k};
        int start[3], step[3];
        for (int a = 0; a < 3; ++a) {
          const bool mirrored = mirror && base[a] % 2 == 1;
          start[a] = base[a] + (mirrored ? 1 : 0);
          step[a] = mirrored ? -1 : 1;
        }
        for (const auto& path : kPaths) {
          int c[3] = {start[0], start[1], start[2]};
          int v[4];
          v[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            c[path[s]] += step[path[s]];
            v[s + 1] = id(c[0], c[1], c[2]);
          }
          AddOriented(mesh, v[0], v[1], v[2], v[3]);
        }
      }
  if (Status s = Validate(mesh, 0.0); !s.ok()) return s.error();
  return mesh;
}

}  // namespace

Expected<TetMesh> MakeTetBall(const TetBallParams& p) {
  if (!(p.radius > 0) || !std::isfinite(p.radius))
    return InvalidArgument("radius", "must be > 0 m");
  if (p.cells < 2 || p.cells > 128 || p.cells % 2 != 0)
    return InvalidArgument("cells", "must be even, within 2..128");
  const int n = p.cells;
  return KuhnGrid(n, n, n, [&](int i, int j, int k) {
    const Vec3 x(2.0 * i / n - 1.0, 2.0 * j / n - 1.0, 2.0 * k / n - 1.0);
    const double l2 = x.norm();
    return l2 > 0 ? Vec3(p.radius * x * x.cwiseAbs().maxCoeff() / l2) : Vec3::Zero();
  });
}

Expected<TetMesh> MakeTetBox(const TetBoxParams& p) {
  for (int a = 0; a < 3; ++a) {
    if (!(p.size[a] > 0 && p.size[a] <= 10))
      return InvalidArgument("size", "each side must be in (0, 10] m");
    if (p.cells[a] < 1 || p.cells[a] > 256)
      return InvalidArgument("cells", "each count must be within 1..256");
  }
  return KuhnGrid(
      p.cells[0], p.cells[1], p.cells[2],
      [&](int i, int j, int k) {
        return Vec3(p.size.x() * (static_cast<double>(i) / p.cells[0] - 0.5),
                    p.size.y() * (static_cast<double>(j) / p.cells[1] - 0.5),
                    p.size.z() * static_cast<double>(k) / p.cells[2]);
      },
      false);
}

TetCylinderParams TorsionCylinder(double length, double radius_base, double radius_tip, int rings) {
  const double mean_radius = 0.5 * (radius_base + radius_tip);
  const int layers = rings * static_cast<int>(std::ceil(3.0 * length / mean_radius));
  return {length, radius_base, radius_tip, rings, layers};
}

TriMesh CompactBoundarySurface(const TetMesh& mesh, std::vector<int>* fem_vertex) {
  const TriMesh all = BoundarySurface(mesh);
  std::vector<int> index(mesh.positions.size(), -1);
  TriMesh out;
  std::vector<int> from;
  for (const Triangle& t : all.triangles) {
    Triangle c;
    for (int k = 0; k < 3; ++k) {
      if (index[t[k]] < 0) {
        index[t[k]] = static_cast<int>(out.positions.size());
        out.positions.push_back(mesh.positions[t[k]]);
        from.push_back(t[k]);
      }
      c[k] = index[t[k]];
    }
    out.triangles.push_back(c);
  }
  if (fem_vertex) *fem_vertex = std::move(from);
  return out;
}

}  // namespace vsurg::geometry
