#include "common/tissue/inclusions.h"

#include <algorithm>
#include <cmath>

#include "common/geometry/distances.h"
#include "common/geometry/tet_embedding.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

Error Refused(const std::string& field, const std::string& why) {
  return Error{ErrorCode::kInvalidArgument, field + ": " + why, field};
}

// The barycentric lattice of order n (inclusions.h): C(n+3, 3) points, equal weights.
std::vector<Eigen::Vector4d> Lattice(int n) {
  std::vector<Eigen::Vector4d> out;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; i + j <= n; ++j)
      for (int k = 0; i + j + k <= n; ++k) {
        const int l = n - i - j - k;
        out.emplace_back(Eigen::Vector4d(i + 0.25, j + 0.25, k + 0.25, l + 0.25) / (n + 1));
      }
  return out;
}

// The scale of one element: exact where it lies wholly inside or outside every inclusion (its
// vertices' ball around the centroid), else the lattice's mean.
double ElementScale(const geometry::TetMesh& mesh, const geometry::Tetrahedron& t,
                    const std::vector<Inclusion>& inclusions,
                    const std::vector<Eigen::Vector4d>& lattice) {
  Vec3 centroid = Vec3::Zero();
  for (int v : t) centroid += 0.25 * mesh.positions[v];
  double reach = 0;
  for (int v : t) reach = std::max(reach, (mesh.positions[v] - centroid).norm());
  // Each inclusion holds the element wholly, or not at all, or in part.
  const bool mixed = std::any_of(inclusions.begin(), inclusions.end(), [&](const Inclusion& c) {
    const double d = (centroid - c.centre).norm();
    return d < c.radius + reach && d + reach > c.radius;
  });
  if (!mixed) return ContrastAt(inclusions, centroid);  // every point has the centroid's
  double sum = 0;
  for (const Eigen::Vector4d& b : lattice) {
    const Vec3 p = b[0] * mesh.positions[t[0]] + b[1] * mesh.positions[t[1]] +
                   b[2] * mesh.positions[t[2]] + b[3] * mesh.positions[t[3]];
    sum += ContrastAt(inclusions, p);
  }
  return sum / static_cast<double>(lattice.size());
}

// splitmix64 (Steele, Lea & Flood 2014): a seed's stream, the same everywhere.
class Stream {
 public:
  explicit Stream(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double Between(double lo, double hi) { return lo + (hi - lo) * Uniform(); }

 private:
  uint64_t state_;
};

// A point of `surface` uniform by area, and the outward normal there.
std::pair<Vec3, Vec3> SurfaceSample(const geometry::TriMesh& surface,
                                    const std::vector<double>& cumulative_area, Stream& rng) {
  const double pick = rng.Uniform() * cumulative_area.back();
  const auto at = std::upper_bound(cumulative_area.begin(), cumulative_area.end(), pick);
  const int t =
      std::min(static_cast<int>(at - cumulative_area.begin()), surface.TriangleCount() - 1);
  const geometry::Triangle& tri = surface.triangles[t];
  double u = rng.Uniform(), v = rng.Uniform();
  if (u + v > 1) u = 1 - u, v = 1 - v;
  const Vec3& a = surface.positions[tri[0]];
  const Vec3 p = a + u * (surface.positions[tri[1]] - a) + v * (surface.positions[tri[2]] - a);
  return {p, geometry::TriangleNormal(surface.positions, tri)};
}

double DistanceTo(const geometry::TriMesh& surface, const Vec3& p) {
  auto at = geometry::ClosestSurfacePoint(surface, p);
  return at.ok() ? (geometry::PositionOf(surface, *at) - p).norm() : 0;
}

// Whether a drawn lump may stay: inside, at a depth in range measured to the palpable surface,
// and apart from the lumps before it.
bool Acceptable(const geometry::TetMesh& tissue, const geometry::TriMesh& boundary,
                const geometry::TriMesh& palpable, const InclusionDraw& draw,
                const std::vector<Inclusion>& before, const Inclusion& lump) {
  for (const Inclusion& other : before)
    if ((other.centre - lump.centre).norm() < other.radius + lump.radius + draw.min_gap)
      return false;
  if (!InsideTissue(tissue, lump.centre)) return false;
  const double depth = DistanceTo(boundary, lump.centre);
  if (depth < draw.min_depth || depth > draw.max_depth) return false;
  return DistanceTo(palpable, lump.centre) <= depth + 1e-9;
}

// A range [lo, hi] with lo ≥ floor, lo ≤ hi, hi > 0, both finite.
Status CheckRange(const std::string& field, double lo, double hi, double floor) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || lo < floor || lo > hi || !(hi > 0))
    return Refused(field, "must be a finite range above zero, the least first");
  return Status::Ok();
}

}  // namespace

bool InsideTissue(const geometry::TetMesh& mesh, const Vec3& p) {
  auto at = geometry::EmbedPoints(mesh, {p});  // the element holding p, or the nearest one
  return at.ok() && (*at)[0].distance <= 1e-9;
}

Status ValidateInclusionDraw(const InclusionDraw& d, const std::string& field) {
  if (d.min_count < 0 || d.max_count > 16 || d.min_count > d.max_count)
    return Refused(field + ".count", "must be 0 to 16 lumps, the least first");
  if (Status s = CheckRange(field + ".diameter", d.min_diameter, d.max_diameter, 1e-4); !s.ok())
    return s;
  if (Status s = CheckRange(field + ".depth", d.min_depth, d.max_depth, 0); !s.ok()) return s;
  if (Status s = CheckRange(field + ".contrast", d.min_contrast, d.max_contrast, 1e-3); !s.ok())
    return s;
  if (d.max_contrast > kMaxInclusionContrast)
    return Refused(field + ".contrast",
                   "must be at most " + std::to_string(static_cast<int>(kMaxInclusionContrast)));
  if (!std::isfinite(d.min_gap) || d.min_gap < 0)
    return Refused(field + ".gap", "must be a finite length >= 0 m");
  return Status::Ok();
}

Expected<std::vector<Inclusion>> DrawInclusions(const geometry::TetMesh& tissue,
                                                const geometry::TriMesh& palpable,
                                                const InclusionDraw& draw, uint64_t seed) {
  if (Status s = ValidateInclusionDraw(draw, "draw"); !s.ok()) return s.error();
  if (palpable.triangles.empty()) return Refused("palpable", "has no triangles");
  const geometry::TriMesh boundary = geometry::BoundarySurface(tissue);
  std::vector<double> cumulative;
  double area = 0;
  for (int t = 0; t < palpable.TriangleCount(); ++t)
    cumulative.push_back(area += geometry::TriangleArea(palpable, t));
  Stream rng(seed);
  const int count =
      draw.min_count + static_cast<int>(rng.Uniform() * (draw.max_count - draw.min_count + 1));
  std::vector<Inclusion> out;
  for (int n = 0; n < count; ++n) {
    bool placed = false;
    for (int attempt = 0; attempt < 2000 && !placed; ++attempt) {
      const auto [point, normal] = SurfaceSample(palpable, cumulative, rng);
      Inclusion lump;
      lump.centre = point - rng.Between(draw.min_depth, draw.max_depth) * normal;
      lump.radius = 0.5 * rng.Between(draw.min_diameter, draw.max_diameter);
      lump.contrast = rng.Between(draw.min_contrast, draw.max_contrast);
      placed = Acceptable(tissue, boundary, palpable, draw, out, lump);
      if (placed) out.push_back(lump);
    }
    if (!placed)
      return Error{ErrorCode::kFailedPrecondition,
                   "draw.depth: no place found for lump " + std::to_string(n + 1) + " of " +
                       std::to_string(count) +
                       " in 2000 tries (a tissue too thin for the depth range, or too small for "
                       "that many lumps apart)",
                   "draw.depth"};
  }
  return out;
}

Status ValidateInclusion(const Inclusion& c, const std::string& field) {
  if (!c.centre.allFinite()) return Refused(field + ".centre", "must be three finite numbers (m)");
  if (!std::isfinite(c.radius) || !(c.radius > 0))
    return Refused(field + ".radius", "must be a finite length > 0 m");
  if (!std::isfinite(c.contrast) || !(c.contrast > 0) || c.contrast > kMaxInclusionContrast)
    return Refused(field + ".contrast",
                   "must be in (0, " + std::to_string(static_cast<int>(kMaxInclusionContrast)) +
                       "] (the inclusion's Young's modulus over the tissue's; 1 is no lump)");
  return Status::Ok();
}

double ContrastAt(const std::vector<Inclusion>& inclusions, const Vec3& p) {
  bool inside = false;
  double hard = 0, soft = 1;
  for (const Inclusion& c : inclusions) {
    if ((p - c.centre).squaredNorm() > c.radius * c.radius) continue;
    inside = true;
    hard = std::max(hard, c.contrast);
    soft = std::min(soft, c.contrast);
  }
  if (!inside) return 1;
  return hard > 1 ? hard : soft;
}

Expected<std::vector<double>> InclusionStiffnessScale(const geometry::TetMesh& mesh,
                                                      const std::vector<Inclusion>& inclusions,
                                                      int lattice_order) {
  for (size_t i = 0; i < inclusions.size(); ++i) {
    const std::string field = "inclusions[" + std::to_string(i) + "]";
    if (Status s = ValidateInclusion(inclusions[i], field); !s.ok()) return s.error();
    if (!InsideTissue(mesh, inclusions[i].centre))
      return Refused(field + ".centre", "lies outside the tissue");
  }
  std::vector<double> scale(mesh.tetrahedra.size(), 1.0);
  if (inclusions.empty()) return scale;
  const std::vector<Eigen::Vector4d> lattice = Lattice(std::max(1, lattice_order));
  for (size_t e = 0; e < mesh.tetrahedra.size(); ++e)
    scale[e] = ElementScale(mesh, mesh.tetrahedra[e], inclusions, lattice);
  return scale;
}

}  // namespace vsurg::tissue
