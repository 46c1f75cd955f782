#include "common/haptics/proxy.h"

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::haptics {
namespace {

using geometry::TriMesh;

// A flat square plate z ∈ [−thickness, 0], x, y ∈ [−0.05, 0.05], closed (a thin box).
TriMesh Plate(double thickness) {
  TriMesh m;
  const double s = 0.05;
  for (double z : {0.0, -thickness}) {
    m.positions.emplace_back(-s, -s, z);
    m.positions.emplace_back(s, -s, z);
    m.positions.emplace_back(s, s, z);
    m.positions.emplace_back(-s, s, z);
  }
  m.triangles = {{0, 1, 2}, {0, 2, 3},  // top, normal +z
                 {4, 6, 5}, {4, 7, 6},  // bottom, normal −z
                 {0, 4, 5}, {0, 5, 1}, {1, 5, 6}, {1, 6, 2},
                 {2, 6, 7}, {2, 7, 3}, {3, 7, 4}, {3, 4, 0}};
  return m;
}

ProxyContact Make(double k = 300, double d = 0, double mu = 0) {
  ProxyParams p;
  p.stiffness = k;
  p.damping = d;
  p.friction = mu;
  return *ProxyContact::Create(p);
}

TEST(ProxyTest, ForceIsStiffnessTimesDepthAlongTheNormal) {
  const TriMesh plate = Plate(0.02);
  const geometry::Bvh bvh(plate);
  ProxyContact proxy = Make();
  proxy.Update(plate.positions, bvh, Vec3(0.01, 0.01, 0.01), 1e-3);
  EXPECT_FALSE(proxy.state().contact);
  const ProxyState& s = proxy.Update(plate.positions, bvh, Vec3(0.01, 0.01, -0.002), 1e-3);
  ASSERT_TRUE(s.contact);
  EXPECT_NEAR((s.scp - Vec3(0.01, 0.01, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(s.force.z(), 300 * 0.002, 1e-12);
  EXPECT_NEAR(s.penetration, 0.002, 1e-12);
  // Sliding sideways inside keeps the proxy above the tip (frictionless).
  const ProxyState& t = proxy.Update(plate.positions, bvh, Vec3(0.015, 0.005, -0.003), 1e-3);
  EXPECT_NEAR((t.scp - Vec3(0.015, 0.005, 0)).norm(), 0, 1e-12);
  // The local model predicts the force at a nearby point exactly for a flat face.
  const Eigen::Vector3d x1(0.016, 0.006, -0.004);
  const Eigen::Vector3d predicted = t.force + t.jacobian * (x1 - Vec3(0.015, 0.005, -0.003));
  EXPECT_NEAR(predicted.z(), 300 * 0.004, 1e-9);
  // A jump farther than max_step moves the proxy by max_step only.
  const Vec3 before = proxy.state().scp;
  const ProxyState& far = proxy.Update(plate.positions, bvh, Vec3(0.04, 0.005, -0.003), 1e-3);
  EXPECT_NEAR((far.scp - before).norm(), 0.01, 1e-12);
  // Leaving ends contact.
  EXPECT_FALSE(proxy.Update(plate.positions, bvh, Vec3(0.02, 0, 0.001), 1e-3).contact);
}

TEST(ProxyTest, NoPopThroughAThinSheet) {
  const TriMesh sheet = Plate(0.001);  // 1 mm thick
  const geometry::Bvh bvh(sheet);
  ProxyContact proxy = Make();
  proxy.Update(sheet.positions, bvh, Vec3(0, 0, 0.01), 1e-3);
  for (int i = 1; i <= 100; ++i) {
    const ProxyState& s =
        proxy.Update(sheet.positions, bvh, Vec3(0, 0, 0.01 - 0.0003 * i), 1e-3);  // down to −2 cm
    if (i > 34) {
      ASSERT_TRUE(s.contact) << i;
      EXPECT_NEAR(s.scp.z(), 0.0, 1e-12) << i;  // stays on the top face, never pops below
      EXPECT_GT(s.force.z(), 0) << i;
    }
  }
}

TEST(ProxyTest, AFastStrokeThroughTheWholeObjectStillHitsTheEntryFace) {
  auto sphere = geometry::MakeSubdividedSphere({0.05, 3, geometry::SphereBase::kOctahedron});
  const geometry::Bvh bvh(*sphere);
  ProxyContact proxy = Make();
  proxy.Update(sphere->positions, bvh, Vec3(0.001, 0.002, 0.08), 1e-3);
  // One update from above the sphere to below it (200 m/s).
  const ProxyState& s = proxy.Update(sphere->positions, bvh, Vec3(0.001, 0.002, -0.12), 1e-3);
  ASSERT_TRUE(s.contact);
  EXPECT_GT(s.scp.z(), 0.04);  // the top, where it entered
  EXPECT_GT(s.force.z(), 0);
}

TEST(ProxyTest, StillTipGainsNoEnergyAndALoopInsideIsPassive) {
  const TriMesh plate = Plate(0.02);
  const geometry::Bvh bvh(plate);
  ProxyContact proxy = Make(300, 2.0);
  proxy.Update(plate.positions, bvh, Vec3(0, 0, 0.005), 1e-3);
  Vec3 f_prev = proxy.Update(plate.positions, bvh, Vec3(0, 0, -0.003), 1e-3).force;
  for (int i = 0; i < 1000; ++i) {
    const Vec3 f = proxy.Update(plate.positions, bvh, Vec3(0, 0, -0.003), 1e-3).force;
    EXPECT_NEAR((f - Vec3(0, 0, 0.9)).norm(), 0, 1e-9);  // constant: no oscillation, no drift
    f_prev = f;
  }
  // A closed loop inside the tissue: the work the coupling does on the hand is never positive.
  double work = 0;
  Vec3 x_prev(0, 0, -0.003);
  for (int i = 1; i <= 2000; ++i) {
    const double a = 2 * M_PI * i / 2000.0;
    const Vec3 x(0.01 * std::sin(a), 0.01 * (1 - std::cos(a)), -0.003 - 0.002 * std::sin(a));
    const Vec3 f = proxy.Update(plate.positions, bvh, x, 1e-3).force;
    work += f.dot(x - x_prev);
    x_prev = x;
  }
  EXPECT_LE(work, 1e-9);
}

TEST(ProxyTest, FrictionHoldsTheProxyInsideTheCone) {
  const TriMesh plate = Plate(0.02);
  const geometry::Bvh bvh(plate);
  ProxyContact proxy = Make(300, 0, 0.5);
  proxy.Update(plate.positions, bvh, Vec3(0, 0, 0.005), 1e-3);
  proxy.Update(plate.positions, bvh, Vec3(0, 0, -0.004), 1e-3);
  // 1 mm sideways against 4 mm deep: tangential 0.3 N ≤ 0.5 × 1.2 N, it sticks.
  const ProxyState& stick = proxy.Update(plate.positions, bvh, Vec3(0.001, 0, -0.004), 1e-3);
  EXPECT_NEAR(stick.scp.x(), 0.0, 1e-12);
  EXPECT_LT(stick.force.x(), 0);  // friction resists the slide
  // 5 mm sideways: outside the cone, it slides.
  const ProxyState& slide = proxy.Update(plate.positions, bvh, Vec3(0.005, 0, -0.004), 1e-3);
  EXPECT_NEAR(slide.scp.x(), 0.005, 1e-12);
}

// The proxy answers from its kept face lists (a surface motion given) exactly as from the tree: a
// tip that comes in from outside, presses 4 mm into the forearm, slides around and leaves, over a
// surface that swells and shifts a little every few updates, with friction; the same contact, the
// same force, update for update.
TEST(ProxyTest, KeptFaceListsGiveTheTreesContact) {
  TriMesh m =
      geometry::MakeLimb(geometry::WithResolution(geometry::ForearmPreset(), 3000))->surface;
  const TriMesh rest = m;
  geometry::Bvh bvh(m);
  ProxyContact kept = Make(300, 1, 0.3), tree = Make(300, 1, 0.3);
  // A side of the forearm 12 cm along it: the surface point on +x and its outward normal there.
  const geometry::ClosestHit side = bvh.Closest(m.positions, Vec3(0.1, 0, 0.12));
  ASSERT_GE(side.triangle, 0);
  const Vec3 n = geometry::TriangleNormal(m, side.triangle), e1 = n.unitOrthogonal(),
             e2 = n.cross(e1);
  double motion = 0;
  int in_contact = 0;
  for (int i = 0; i < 4000; ++i) {
    const double t = i * 1e-3;
    // Out 5 mm → in 4 mm over the first 0.5 s, a 6 mm circle at 1 Hz, out again after 3.5 s.
    const double depth =
        t < 0.5 ? -0.005 + 0.018 * t : (t < 3.5 ? 0.004 : 0.004 - 0.02 * (t - 3.5));
    const double a = 2 * M_PI * t;
    const Vec3 hip = side.point - depth * n + 0.006 * (std::cos(a) * e1 + std::sin(a) * e2);
    if (i % 4 == 0) {  // the tissue breathes: ±0.5 mm along x and a swell, 1.5 Hz
      double largest = 0;
      for (size_t v = 0; v < m.positions.size(); ++v) {
        const Vec3 to = rest.positions[v] +
                        5e-4 * std::sin(3 * M_PI * t) * Vec3(1, 0, 0.2 * rest.positions[v].z());
        largest = std::max(largest, (to - m.positions[v]).norm());
        m.positions[v] = to;
      }
      bvh.Refit(m.positions);
      motion += largest;
    }
    const ProxyState a_state = kept.Update(m.positions, bvh, hip, 1e-3, motion);
    const ProxyState& b_state = tree.Update(m.positions, bvh, hip, 1e-3);
    ASSERT_EQ(a_state.contact, b_state.contact) << i;
    in_contact += a_state.contact;
    ASSERT_LT((a_state.force - b_state.force).norm(), 1e-9) << i;
    ASSERT_LT((a_state.scp - b_state.scp).norm(), 1e-12) << i;
  }
  EXPECT_GT(in_contact, 2500);
}

TEST(ProxyTest, BadParametersAreRejected) {
  ProxyParams p;
  p.stiffness = -1;
  EXPECT_EQ(ProxyContact::Create(p).error().field, "stiffness");
  p = ProxyParams{};
  p.max_step = 0;
  EXPECT_EQ(ProxyContact::Create(p).error().field, "max_step");
}

}  // namespace
}  // namespace vsurg::haptics
