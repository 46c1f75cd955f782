#include "client/render/shapes.h"

#include <cmath>
#include <numbers>

namespace vsurg::client {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

uint32_t Push(ShapeMesh& m, const Eigen::Vector3f& p, const Eigen::Vector3f& n) {
  m.positions.push_back(p);
  m.normals.push_back(n.normalized());
  return static_cast<uint32_t>(m.positions.size() - 1);
}

}  // namespace

void AddCylinder(ShapeMesh& m, float r0, float r1, float z0, float z1, int segments,
                 const Eigen::Affine3f& pose) {
  const Eigen::Matrix3f turn = pose.linear();
  // The side's normal leans by the cone's slope.
  const float slope = (r0 - r1) / std::max(z1 - z0, 1e-9f);
  const uint32_t base = static_cast<uint32_t>(m.positions.size());
  for (int k = 0; k <= segments; ++k) {
    const float a = 2 * kPi * static_cast<float>(k) / static_cast<float>(segments);
    const Eigen::Vector3f radial(std::cos(a), std::sin(a), 0);
    const Eigen::Vector3f n = turn * (radial + Eigen::Vector3f(0, 0, slope));
    Push(m, pose * Eigen::Vector3f(r0 * radial.x(), r0 * radial.y(), z0), n);
    Push(m, pose * Eigen::Vector3f(r1 * radial.x(), r1 * radial.y(), z1), n);
  }
  for (int k = 0; k < segments; ++k) {
    const uint32_t a = base + 2 * k, b = a + 1, c = a + 2, d = a + 3;
    m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
  }
  // The end discs.
  for (int end = 0; end < 2; ++end) {
    const float z = end ? z1 : z0, r = end ? r1 : r0;
    if (r <= 0) continue;
    const Eigen::Vector3f n = turn * Eigen::Vector3f(0, 0, end ? 1.f : -1.f);
    const uint32_t centre = Push(m, pose * Eigen::Vector3f(0, 0, z), n);
    for (int k = 0; k <= segments; ++k) {
      const float a = 2 * kPi * static_cast<float>(k) / static_cast<float>(segments);
      Push(m, pose * Eigen::Vector3f(r * std::cos(a), r * std::sin(a), z), n);
    }
    for (int k = 0; k < segments; ++k) {
      const uint32_t a = centre + 1 + k, b = a + 1;
      if (end)
        m.indices.insert(m.indices.end(), {centre, a, b});
      else
        m.indices.insert(m.indices.end(), {centre, b, a});
    }
  }
}

void AddSphere(ShapeMesh& m, float radius, const Eigen::Vector3f& centre, int rings, int segments) {
  const uint32_t base = static_cast<uint32_t>(m.positions.size());
  for (int i = 0; i <= rings; ++i) {
    const float theta = kPi * static_cast<float>(i) / static_cast<float>(rings);
    for (int k = 0; k <= segments; ++k) {
      const float phi = 2 * kPi * static_cast<float>(k) / static_cast<float>(segments);
      const Eigen::Vector3f n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              -std::cos(theta));
      Push(m, centre + radius * n, n);
    }
  }
  const uint32_t row = static_cast<uint32_t>(segments + 1);
  for (int i = 0; i < rings; ++i)
    for (int k = 0; k < segments; ++k) {
      const uint32_t a = base + i * row + k, b = a + 1, c = a + row, d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, c, b, d, c});
    }
}

void AddBox(ShapeMesh& m, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
            const Eigen::Affine3f& pose) {
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      Eigen::Vector3f n = Eigen::Vector3f::Zero();
      n[axis] = side ? 1.f : -1.f;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      uint32_t corner[4];
      for (int c = 0; c < 4; ++c) {
        Eigen::Vector3f p;
        p[axis] = side ? hi[axis] : lo[axis];
        p[u] = (c == 1 || c == 2) ? hi[u] : lo[u];
        p[v] = (c >= 2) ? hi[v] : lo[v];
        corner[c] = Push(m, pose * p, pose.linear() * n);
      }
      if (side)
        m.indices.insert(m.indices.end(),
                         {corner[0], corner[1], corner[2], corner[0], corner[2], corner[3]});
      else
        m.indices.insert(m.indices.end(),
                         {corner[0], corner[2], corner[1], corner[0], corner[3], corner[2]});
    }
}

InstrumentParts MakeInstrument(sim::Instrument kind) {
  InstrumentParts parts;
  constexpr int kSides = 24;
  switch (kind) {
    case sim::Instrument::kProbe:
      // A blunt ball-tipped probe: the ball's bottom is the tip.
      AddSphere(parts.steel, 0.0025f, {0, 0, 0.0025f}, 10, kSides);
      AddCylinder(parts.steel, 0.0015f, 0.0015f, 0.0025f, 0.10f, kSides);
      AddCylinder(parts.steel, 0.0015f, 0.0042f, 0.10f, 0.112f, kSides);
      AddCylinder(parts.handle, 0.0055f, 0.0060f, 0.112f, 0.19f, kSides);
      AddSphere(parts.handle, 0.0060f, {0, 0, 0.19f}, 8, kSides);
      break;
    case sim::Instrument::kGrasper:
      // Laparoscopic forceps: two serrated jaws on a 5 mm shaft.
      parts.has_jaws = true;
      parts.hinge = {0, 0, 0.016f};
      parts.open_rad = 0.30f;
      for (int tooth = 0; tooth < 6; ++tooth) {  // the jaw's teeth, across its inner face
        const float z = 0.0015f + 0.0024f * static_cast<float>(tooth);
        AddBox(parts.jaw, {-0.0016f, 0.0f, z}, {0.0016f, 0.0004f, z + 0.0011f});
      }
      AddBox(parts.jaw, {-0.0016f, 0.0004f, 0.0f}, {0.0016f, 0.0016f, 0.017f});
      AddCylinder(parts.steel, 0.0025f, 0.0025f, 0.017f, 0.14f, kSides);
      AddCylinder(parts.handle, 0.0025f, 0.0070f, 0.14f, 0.15f, kSides);
      AddCylinder(parts.handle, 0.0070f, 0.0065f, 0.15f, 0.21f, kSides);
      break;
    case sim::Instrument::kNeedle:
      // An 18-gauge needle (1.27 mm across) with its bevelled point, 70 mm long with a depth
      // mark every centimetre (the handle's dark rings), on a hub and a 5 ml syringe.
      AddCylinder(parts.steel, 0.0f, 0.00064f, 0.0f, 0.003f, kSides);
      for (int cm = 0; cm < 7; ++cm) {
        const float z0 = 0.003f + 0.01f * static_cast<float>(cm);
        AddCylinder(parts.steel, 0.00064f, 0.00064f, z0, z0 + 0.0093f, kSides);
        AddCylinder(parts.handle, 0.00068f, 0.00068f, z0 + 0.0093f, z0 + 0.01f, kSides);
      }
      AddCylinder(parts.handle, 0.0012f, 0.0035f, 0.073f, 0.085f, kSides);
      AddCylinder(parts.handle, 0.0070f, 0.0070f, 0.085f, 0.145f, kSides);
      AddCylinder(parts.handle, 0.0110f, 0.0110f, 0.145f, 0.148f, kSides);
      break;
    case sim::Instrument::kScalpel:
      // A number 11 blade (its point at the tip, 0.4 mm thick, 6 mm at its back) on a No. 3
      // handle, 125 mm long.
      AddBox(parts.steel, {-0.0002f, -0.0010f, 0.0f}, {0.0002f, 0.0010f, 0.006f});
      AddBox(parts.steel, {-0.0002f, -0.0030f, 0.006f}, {0.0002f, 0.0030f, 0.040f});
      AddBox(parts.handle, {-0.0012f, -0.0040f, 0.040f}, {0.0012f, 0.0040f, 0.165f});
      break;
    case sim::Instrument::kGrip:
      // A twisting grip: two broad padded jaws that close on the wrist, a shaft and a T-bar.
      parts.has_jaws = true;
      parts.hinge = {0, 0, 0.024f};
      parts.open_rad = 0.22f;
      AddBox(parts.jaw, {-0.008f, 0.0f, 0.0f}, {0.008f, 0.003f, 0.024f});
      AddCylinder(parts.steel, 0.0035f, 0.0035f, 0.024f, 0.105f, kSides);
      AddCylinder(parts.handle, 0.0065f, 0.0065f, -0.045f, 0.045f, kSides,
                  Eigen::Affine3f(Eigen::Translation3f(0, 0, 0.11f) *
                                  Eigen::AngleAxisf(kPi / 2, Eigen::Vector3f::UnitY())));
      break;
  }
  return parts;
}

void FlatMesh::Vertex(const Eigen::Vector3d& p, const Eigen::Vector4f& c) {
  data.insert(data.end(), {static_cast<float>(p.x()), static_cast<float>(p.y()),
                           static_cast<float>(p.z()), c[0], c[1], c[2], c[3]});
}

namespace {

// The k-th of `segments` points around a circle of `radius` at right angles to the segment
// from → to, as an offset from the circle's centre. MakeRing: false for a degenerate segment.
struct Ring {
  Eigen::Vector3d e1, e2;
  double radius;
  int segments;
  Eigen::Vector3d operator()(int k) const {
    const double t = 2 * std::numbers::pi * k / segments;
    return radius * (std::cos(t) * e1 + std::sin(t) * e2);
  }
};
bool MakeRing(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius, int segments,
              Ring& ring) {
  const Eigen::Vector3d axis = to - from;
  if (!(axis.norm() > 0) || !from.allFinite() || !to.allFinite()) return false;
  ring.e1 = axis.unitOrthogonal();
  ring.e2 = axis.normalized().cross(ring.e1);
  ring.radius = radius;
  ring.segments = segments;
  return true;
}

}  // namespace

void FlatMesh::Tube(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius,
                    const Eigen::Vector4f& colour, int segments) {
  Ring ring;
  if (!MakeRing(a, b, radius, segments, ring)) return;
  for (int k = 0; k < segments; ++k) {
    const Eigen::Vector3d r0 = ring(k), r1 = ring(k + 1);
    Vertex(a + r0, colour);
    Vertex(a + r1, colour);
    Vertex(b + r0, colour);
    Vertex(b + r0, colour);
    Vertex(a + r1, colour);
    Vertex(b + r1, colour);
  }
}

void FlatMesh::Cone(const Eigen::Vector3d& base, const Eigen::Vector3d& apex, double radius,
                    const Eigen::Vector4f& colour, int segments) {
  Ring ring;
  if (!MakeRing(base, apex, radius, segments, ring)) return;
  for (int k = 0; k < segments; ++k) {
    Vertex(base + ring(k), colour);
    Vertex(base + ring(k + 1), colour);
    Vertex(apex, colour);
  }
}

void FlatMesh::Arc(const Eigen::Vector3d& centre, const Eigen::Vector3d& axis,
                   const Eigen::Vector3d& zero, double radius, double a0, double a1,
                   double thickness, const Eigen::Vector4f& colour) {
  if (!std::isfinite(a0) || !std::isfinite(a1) || std::abs(a1 - a0) < 1e-4) return;
  const int steps = std::max(2, static_cast<int>(std::abs(a1 - a0) / 0.05));
  const Eigen::Vector3d k = axis.normalized();
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (int i = 0; i <= steps; ++i) {
    const double a = a0 + (a1 - a0) * i / steps;
    const Eigen::Vector3d p = centre + radius * (Eigen::AngleAxisd(a, k) * zero.normalized());
    if (i > 0) Tube(previous, p, thickness, colour, 6);
    previous = p;
  }
}

}  // namespace vsurg::client
