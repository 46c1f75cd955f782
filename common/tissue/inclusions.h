// Stiff (or soft) inclusions in a tissue: a lump under the surface that palpation looks for
// (DESIGN.md, Model 3: heterogeneous tissue). Each inclusion is a ball of the surrounding tissue's
// material with its Young's modulus multiplied by a contrast; the FEM carries it per element.
//
// An element partly inside takes the volume-weighted mean of the moduli it holds (Voigt's
// bound, the rule of mixtures), its inside share measured at the points of a barycentric
// lattice of order n: the C(n+3, 3) points whose coordinates are (i + 1/4)/(n + 1) for
// non-negative integers i summing to n (every point inside, each standing for an equal share of
// the element's volume). Under refinement the share converges to the exact one and the mixed
// elements' layer to zero thickness, so the FEM's answer converges to the sharp inclusion's.
// Overlapping inclusions: a point takes the largest contrast of those it lies in (a soft one
// alone, below 1, sets it).
//
// Units: m; contrast is dimensionless (E_inclusion / E_tissue).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::tissue {

struct Inclusion {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // m
  double radius = 0.005;                             // m
  double contrast = 5;  // E inside / E around; 1 is no lump, below 1 a softer one (a cyst)
};

// The range a contrast must lie in: above zero, and at most this (a stiffer inclusion is held
// as rigid by any tissue around it, and the stiffness matrix's conditioning worsens with it).
inline constexpr double kMaxInclusionContrast = 100;

// A finite centre, a radius > 0 and a contrast in (0, kMaxInclusionContrast]; the error names
// `field` and the part that is wrong (e.g. "tissue.inclusions[1].radius").
Status ValidateInclusion(const Inclusion& inclusion, const std::string& field);

// The contrast at a point (1 where no inclusion holds it).
double ContrastAt(const std::vector<Inclusion>& inclusions, const Eigen::Vector3d& p);

// Per tetrahedron of `mesh`, the factor its Young's modulus is multiplied by (FemParams::
// element_stiffness_scale); all 1 with no inclusions. Refused, naming "inclusions[i]", when an
// inclusion is invalid or its centre lies in no tetrahedron (outside the tissue); one that
// reaches through the surface is kept, its outside part simply not tissue.
Expected<std::vector<double>> InclusionStiffnessScale(const geometry::TetMesh& mesh,
                                                      const std::vector<Inclusion>& inclusions,
                                                      int lattice_order = 6);

// Whether a point lies in the tissue: in some tetrahedron of `mesh` (geometry::EmbedPoints;
// set-up only).
bool InsideTissue(const geometry::TetMesh& mesh, const Eigen::Vector3d& p);

// Cases drawn at random for palpation, so that no two attempts hide the same lumps: how many
// (possibly none), how large, how deep under the surface a tool can reach (the centre's distance
// to the nearest point of the tissue's surface, which must lie on the palpable part: a lump
// nearer the table than the top is not one a trainee can find), how stiff, and how far apart
// (between two lumps' surfaces, so that each is felt on its own).
struct InclusionDraw {
  int min_count = 1, max_count = 1;
  double min_diameter = 0.005, max_diameter = 0.015;  // m
  double min_depth = 0.005, max_depth = 0.025;        // m
  double min_contrast = 3, max_contrast = 10;
  double min_gap = 0.005;  // m
};

// Counts in 0..16 (min ≤ max), every length finite and > 0 (depths ≥ 0) with min ≤ max, and
// contrasts in (0, kMaxInclusionContrast] with min ≤ max; the error names `field` and the part.
Status ValidateInclusionDraw(const InclusionDraw& draw, const std::string& field);

// One case, the same for the same seed on every machine (its own 64-bit generator, splitmix64,
// not the standard library's distributions, whose algorithms differ between libraries). Each lump:
// a point on `palpable` (uniform by area: the surface a tool can reach, outward normals), a
// depth, a diameter and a contrast uniform in their ranges, its centre that depth inward along
// the normal; kept when the centre is in `tissue`, its distance to the tissue's whole surface
// (geometry::BoundarySurface) is within the depth range and is its distance to `palpable`, and
// it keeps the gap to the lumps drawn before. kFailedPrecondition, naming "depth", when 2,000
// tries of one lump find no such place (a depth range the tissue is too thin for).
Expected<std::vector<Inclusion>> DrawInclusions(const geometry::TetMesh& tissue,
                                                const geometry::TriMesh& palpable,
                                                const InclusionDraw& draw, uint64_t seed);

}  // namespace vsurg::tissue
