#include "common/tissue/inclusions.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

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

// Whether p lies in the tetrahedron (its barycentric coordinates all ≥ −1e-9).
bool Contains(const geometry::TetMesh& mesh, const geometry::Tetrahedron& t, const Vec3& p) {
  const Vec3& a = mesh.positions[t[0]];
  Eigen::Matrix3d d;
  d << mesh.positions[t[1]] - a, mesh.positions[t[2]] - a, mesh.positions[t[3]] - a;
  const Vec3 b = d.inverse() * (p - a);
  return b.minCoeff() >= -1e-9 && b.sum() <= 1 + 1e-9;
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

}  // namespace

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
    const bool inside = std::any_of(
        mesh.tetrahedra.begin(), mesh.tetrahedra.end(),
        [&](const geometry::Tetrahedron& t) { return Contains(mesh, t, inclusions[i].centre); });
    if (!inside) return Refused(field + ".centre", "lies outside the tissue");
  }
  std::vector<double> scale(mesh.tetrahedra.size(), 1.0);
  if (inclusions.empty()) return scale;
  const std::vector<Eigen::Vector4d> lattice = Lattice(std::max(1, lattice_order));
  for (size_t e = 0; e < mesh.tetrahedra.size(); ++e)
    scale[e] = ElementScale(mesh, mesh.tetrahedra[e], inclusions, lattice);
  return scale;
}

}  // namespace vsurg::tissue
