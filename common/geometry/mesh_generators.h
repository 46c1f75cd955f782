// Procedural meshes: the subdivided sphere of the mass-spring paper §2.1 and tapered-cylinder
// limbs.
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

// ---- Sphere by triangle subdivision (the mass-spring paper §2.1)
// ------------------------------------------- Each level splits every triangle into four through
// its edge midpoints, which are pushed out to the sphere. From an octahedron the vertex counts are
// 4·4^L + 2: 6, 18, 66, 258, 1026, 4098, so the paper's "about 256" and "about 1024" particles are
// levels 3 and 4. From an icosahedron they are 10·4^L + 2: 12, 42, 162, 642, 2562.
enum class SphereBase { kOctahedron, kIcosahedron };

struct SphereParams {
  double radius = 0.05;  // m
  int levels = 3;        // subdivision levels, 0..8
  SphereBase base = SphereBase::kOctahedron;
  Vec3 centre = Vec3::Zero();  // omit it in aggregate initialisation: `{}` leaves an Eigen vector
                               // uninitialised rather than zero
};

Expected<TriMesh> MakeSubdividedSphere(const SphereParams& params);

// Vertex count a sphere of that base and level has.
int SphereVertexCount(SphereBase base, int levels);

// The level whose vertex count is nearest target_vertices (ties to the smaller level).
int SphereLevelsForVertexCount(SphereBase base, int target_vertices);

// ---- Limb: a tapered cylinder with a centreline ------------------------------------------------
// The limb runs along +z from the proximal end (z = 0: elbow, knee) to the distal end
// (z = length: wrist, ankle); the radius tapers linearly between the two ends. The surface is
// closed: `rings_along` cross-sections of `segments_around` vertices, plus one centre vertex on
// each end cap. V = rings·segments + 2, F = 2·rings·segments.
struct LimbParams {
  double length = 0.25;           // m
  double radius_proximal = 0.04;  // m
  double radius_distal = 0.03;    // m
  int segments_around = 60;       // vertices per cross-section, ≥ 3
  int rings_along = 103;          // cross-sections including both ends, ≥ 2
};

// Forearm (DESIGN.md default tissue): 25 cm, radius 4 cm at the elbow tapering to 3 cm at the
// wrist. The default resolution gives 6182 vertices and 12360 triangles, the size of the
// coil-spring paper's arm (6185 particles, 12362 triangles).
LimbParams ForearmPreset();
// Calf: 36 cm from below the knee to the ankle, radius 5.5 cm tapering to 3.5 cm.
LimbParams CalfPreset();

// Scales the resolution of a preset so the vertex count is close to target_vertices, keeping
// the spacing around and along about equal in proportion to the preset.
LimbParams WithResolution(LimbParams params, int target_vertices);

struct Limb {
  TriMesh surface;
  std::vector<Vec3> centreline;  // cross-section centres, proximal → distal (a polyline)
  LimbParams params;

  double RadiusAt(double z) const;  // m, linear taper, z clamped to [0, length]
};

Expected<Limb> MakeLimb(const LimbParams& params);

}  // namespace vsurg::geometry
