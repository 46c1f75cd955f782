// Geometry the view builds on the CPU: the instruments' parts (lit, in the instrument's own
// frame: the tip at the origin, the shaft along +z toward the hand) and the guidance marks
// (unlit, coloured, in the scene frame). Units: metres. Nothing here touches OpenGL.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/sim/visual_model.h"

namespace vsurg::client {

struct ShapeMesh {
  std::vector<Eigen::Vector3f> positions, normals;
  std::vector<uint32_t> indices;
};

// A truncated cone from radius r0 at z0 to r1 at z1 about the z axis, closed at both ends,
// placed by `pose`.
void AddCylinder(ShapeMesh& m, float r0, float r1, float z0, float z1, int segments,
                 const Eigen::Affine3f& pose = Eigen::Affine3f::Identity());
void AddSphere(ShapeMesh& m, float radius, const Eigen::Vector3f& centre, int rings, int segments);
// An axis-aligned box placed by `pose`, flat-shaded.
void AddBox(ShapeMesh& m, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
            const Eigen::Affine3f& pose = Eigen::Affine3f::Identity());

// An instrument's parts: steel, the dark handle, and (grasper, grip) one jaw drawn twice, turned
// about the hinge (an axis along x through `hinge`) by ±the opening.
struct InstrumentParts {
  ShapeMesh steel, handle, jaw;
  bool has_jaws = false;
  Eigen::Vector3f hinge = Eigen::Vector3f::Zero();
  float open_rad = 0;  // each jaw's turn when the button is up; closed (0) while held
};
InstrumentParts MakeInstrument(sim::Instrument kind);

// Unlit triangles with a colour per vertex: x, y, z, r, g, b, a per vertex.
struct FlatMesh {
  std::vector<float> data;
  void Clear() { data.clear(); }
  size_t vertices() const { return data.size() / 7; }
  void Vertex(const Eigen::Vector3d& p, const Eigen::Vector4f& c);
  // A tube of `segments` sides from a to b.
  void Tube(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius,
            const Eigen::Vector4f& colour, int segments = 8);
  void Cone(const Eigen::Vector3d& base, const Eigen::Vector3d& apex, double radius,
            const Eigen::Vector4f& colour, int segments = 12);
  // An arc about `axis` through `centre`, starting at the direction `zero` (perpendicular to
  // the axis) and turning from angle a0 to a1 (rad, right-handed about the axis), drawn as a
  // tube of radius `thickness`.
  void Arc(const Eigen::Vector3d& centre, const Eigen::Vector3d& axis, const Eigen::Vector3d& zero,
           double radius, double a0, double a1, double thickness, const Eigen::Vector4f& colour);
};

}  // namespace vsurg::client
