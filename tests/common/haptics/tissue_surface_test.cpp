#include "common/haptics/tissue_surface.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::haptics {
namespace {

constexpr double kRadius = 0.05, kStiffness = 300, kDamping = 2, kReach = 0.03;

// A 5 cm sphere at the origin, its contact 300 N/m everywhere but for the vertex nearest the top.
SurfaceSpec Sphere(double top_stiffness = kStiffness) {
  geometry::SphereParams p;
  p.radius = kRadius;
  p.levels = 4;
  auto mesh = geometry::MakeSubdividedSphere(p);
  EXPECT_TRUE(mesh.ok());
  SurfaceSpec spec;
  spec.positions = mesh->positions;
  spec.triangles = mesh->triangles;
  spec.stiffness.assign(spec.positions.size(), kStiffness);
  for (size_t i = 0; i < spec.positions.size(); ++i)
    if (spec.positions[i].z() > kRadius * 0.999) spec.stiffness[i] = top_stiffness;
  spec.damping = kDamping;
  spec.reach = kReach;
  return spec;
}

TEST(TissueSurfaceTest, TheSurfaceAheadIsTheNearestFacesPlaneWithItsStiffness) {
  auto surface = TissueSurface::Create(Sphere(600));
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  LocalModel m;
  int start = -1;
  // 1 cm above the top vertex (600 N/m there): the plane through it, facing up.
  ASSERT_TRUE((*surface)->Ahead(Vec3(0, 0, kRadius + 0.01), m, start));
  EXPECT_EQ(m.kind, LocalModel::Kind::kContact);
  EXPECT_NEAR(m.normal.z(), 1, 1e-2);
  EXPECT_NEAR(m.position0.z(), kRadius, 1e-3);
  EXPECT_NEAR(-m.normal.dot(m.jacobian * m.normal), 600, 1);
  EXPECT_EQ(m.contact_damping, kDamping);
  EXPECT_TRUE(m.force0.isZero());
  // Beyond the reach, and inside the sphere: nothing ahead.
  EXPECT_FALSE((*surface)->Ahead(Vec3(0, 0, kRadius + 0.04), m, start));
  EXPECT_FALSE((*surface)->Ahead(Vec3(0, 0, kRadius - 0.002), m, start));
  EXPECT_FALSE(
      (*surface)->Ahead(Vec3::Constant(std::numeric_limits<double>::quiet_NaN()), m, start));
}

TEST(TissueSurfaceTest, AContactBeginsWhereTheTipCrossesAndEndsWhereItLeaves) {
  auto surface = TissueSurface::Create(Sphere());
  ASSERT_TRUE(surface.ok());
  SurfaceContact contact(*surface);
  // Down the side at x = 2 cm (off any vertex), 0.1 mm per 1 ms cycle (0.1 m/s), then back up.
  const double x0 = 0.02, surface_z = std::sqrt(kRadius * kRadius - x0 * x0);
  const Vec3 down(0, 0, -0.1);
  double first_felt = std::numeric_limits<double>::quiet_NaN();
  Vec3 f;
  for (int k = 0; k <= 400; ++k) {
    const Vec3 x(x0, 0, surface_z + 0.02 - 1e-4 * k);
    ASSERT_TRUE(contact.Render(x, down, f)) << k;
    if (std::isnan(first_felt) && f.norm() > 0) first_felt = x.z();
    if (x.z() > surface_z + 1e-4) {
      EXPECT_EQ(f.norm(), 0) << "felt above the surface at " << k;
    }
  }
  // Felt from the first cycle below the surface (the faces are within 0.1 mm of the sphere).
  EXPECT_NEAR(first_felt, surface_z, 2e-4);
  EXPECT_TRUE(contact.in_contact());
  // 2 cm down along z is about 1.6 cm along the normal there: k·depth plus the damping's push.
  const Vec3 deep(x0, 0, surface_z - 0.02);
  const Vec3 n = Vec3(x0, 0, surface_z).normalized();
  contact.Render(deep, Vec3::Zero(), f);
  EXPECT_NEAR(f.norm(), kStiffness * 0.02 * n.z(), 0.3);
  EXPECT_GT(f.dot(n), 0) << "the surface pushes out";
  // Moving in adds the damping's push, moving out takes it away but never pulls.
  Vec3 in_f, out_f;
  contact.Render(deep, down, in_f);
  contact.Render(deep, -down * 100, out_f);
  EXPECT_GT(in_f.norm(), f.norm());
  EXPECT_GE(out_f.dot(n), 0);
  // Back out: nothing once the tip is above the plane it went in by.
  contact.Render(Vec3(x0, 0, surface_z + 0.001), -down, f);
  EXPECT_EQ(f.norm(), 0);
  EXPECT_FALSE(contact.in_contact());
}

TEST(TissueSurfaceTest, ATipAlreadyInsideGetsNothingUntilItHasLeft) {
  auto surface = TissueSurface::Create(Sphere());
  ASSERT_TRUE(surface.ok());
  SurfaceContact contact(*surface);
  Vec3 f;
  // Taken over with the tip 5 mm in (the server's contact was just let go): not the surface's.
  EXPECT_FALSE(contact.Render(Vec3(0, 0, kRadius - 0.005), Vec3::Zero(), f));
  EXPECT_EQ(f.norm(), 0);
  // Out, then back in: felt.
  EXPECT_TRUE(contact.Render(Vec3(0, 0, kRadius + 0.001), Vec3::Zero(), f));
  EXPECT_TRUE(contact.Render(Vec3(0, 0, kRadius - 0.001), Vec3::Zero(), f));
  EXPECT_NEAR(f.z(), kStiffness * 0.001, 0.05);
  // A server's contact or grasp takes it: the next contact begins only after leaving again.
  contact.Yield();
  EXPECT_FALSE(contact.Render(Vec3(0, 0, kRadius - 0.002), Vec3::Zero(), f));
  // A crossing straight through a thin part is held by the plane it came to: the tip 6 cm below
  // the top, nearer the bottom than the top, still gets the top's push, upward.
  EXPECT_TRUE(contact.Render(Vec3(0, 0, kRadius + 0.001), Vec3::Zero(), f));
  for (double z = kRadius; z > -0.03; z -= 0.0005) contact.Render(Vec3(0, 0, z), Vec3::Zero(), f);
  EXPECT_GT(f.z(), 0);
}

// With the tissue's law the contact is the proxy's spring in series with a Kelvin–Voigt point:
// a quick press first meets the damper (stiffer than the series spring), and held, it relaxes to
// the series spring k·k_t/(k + k_t), never below it and never pulling.
TEST(TissueSurfaceTest, WithTheTissuesLawAHeldPressRelaxesToTheSeriesSpring) {
  SurfaceSpec spec = Sphere();
  spec.tissue_stiffness = 100;
  spec.tissue_damping = 10;
  spec.damping = 0;
  auto surface = TissueSurface::Create(spec);
  ASSERT_TRUE(surface.ok());
  SurfaceContact contact(*surface, 1e-3);
  Vec3 f;
  ASSERT_TRUE(contact.Render(Vec3(0, 0, kRadius + 0.001), Vec3::Zero(), f));
  // 4 mm in over 20 cycles (0.2 m/s), then held for 3 s.
  double pressed = 0;
  for (int k = 1; k <= 20; ++k) {
    contact.Render(Vec3(0, 0, kRadius + 0.001 - 0.00025 * k), Vec3(0, 0, -0.25), f);
    pressed = f.z();
  }
  const double depth = 0.004, series = kStiffness * 100 / (kStiffness + 100) * depth;
  EXPECT_GT(pressed, 1.2 * series) << "the damper resists a quick press";
  EXPECT_LT(pressed, kStiffness * depth + 1e-9) << "never above the proxy's spring";
  for (int k = 0; k < 3000; ++k) contact.Render(Vec3(0, 0, kRadius - 0.004), Vec3::Zero(), f);
  EXPECT_NEAR(f.z(), series, 0.01 * series);
  // Back out: nothing, and in again from the tissue at rest.
  contact.Render(Vec3(0, 0, kRadius + 0.002), Vec3::Zero(), f);
  EXPECT_EQ(f.norm(), 0);
  // Without the law the same held press is the proxy's spring.
  SurfaceContact plain(*TissueSurface::Create(Sphere()), 1e-3);
  plain.Render(Vec3(0, 0, kRadius + 0.001), Vec3::Zero(), f);
  plain.Render(Vec3(0, 0, kRadius - 0.004), Vec3::Zero(), f);
  EXPECT_NEAR(f.z(), kStiffness * depth, 0.01 * kStiffness * depth);  // the face tilts a little
  // A law out of bounds is refused.
  spec.tissue_damping = -1;
  EXPECT_FALSE(TissueSurface::Create(spec).ok());
}

// A face whose corners yield under a press: at its centroid the face sinks flat (its normal
// kept); off the centroid the corner nearest the point sinks most and the face tilts towards it,
// more the deeper; no yield, no tilt. SurfaceContact renders along that normal only where the
// surface says its corners yield (a mass-spring surface), else along the face's rest normal.
TEST(TissueSurfaceTest, AFaceWhoseCornersYieldTiltsTowardsTheCornerPressed) {
  SurfaceSpec spec;
  spec.positions = {Vec3(0, 0, 0), Vec3(0.01, 0, 0), Vec3(0, 0.01, 0)};
  spec.triangles = {{0, 1, 2}};
  spec.stiffness.assign(3, kStiffness);
  auto flat = TissueSurface::Create(spec);
  ASSERT_TRUE(flat.ok());
  // The centroid's weights, and those of (2 mm, 2 mm) near corner 0.
  const Vec3 centroid(1.0 / 3, 1.0 / 3, 1.0 / 3), near_a(0.6, 0.2, 0.2);
  EXPECT_NEAR((*flat)->YieldedNormal(0, centroid, 0.003).z(), 1, 1e-12);
  EXPECT_NEAR((*flat)->YieldedNormal(0, near_a, 0).z(), 1, 1e-12);
  const Vec3 shallow = (*flat)->YieldedNormal(0, near_a, 0.001),
             deep = (*flat)->YieldedNormal(0, near_a, 0.003);
  EXPECT_NEAR(shallow.norm(), 1, 1e-12);
  // Corner 0 (the origin) sinks most: the face's normal leans towards it, −x and −y alike.
  EXPECT_LT(shallow.x(), -0.01);
  EXPECT_NEAR(shallow.x(), shallow.y(), 1e-12);
  EXPECT_LT(deep.x(), shallow.x());
  // The sinks reproduce the yield at the point: w = (0.6, 0.2, 0.2), each corner w_i·y/Σw².
  const double y = 0.003, w2 = 0.36 + 0.04 + 0.04;
  const Vec3 a(0, 0, -0.6 * y / w2), b(0.01, 0, -0.2 * y / w2), c(0, 0.01, -0.2 * y / w2);
  EXPECT_NEAR(0.6 * a.z() + 0.2 * b.z() + 0.2 * c.z(), -y, 1e-15);
  EXPECT_NEAR((b - a).cross(c - a).normalized().dot(deep), 1, 1e-12);

  // Rendered: a press near a vertex of the sphere's top face, with the tissue's law.
  SurfaceSpec ball = Sphere();
  ball.tissue_stiffness = 100, ball.tissue_damping = 10, ball.damping = 0;
  const auto press = [&](bool corners) {
    ball.corners_yield = corners;
    SurfaceContact contact(*TissueSurface::Create(ball), 1e-3);
    Vec3 f;
    const Vec3 at(0.003, 0.002, kRadius + 0.001);
    contact.Render(at, Vec3::Zero(), f);
    for (int k = 0; k < 500; ++k) contact.Render(at - Vec3(0, 0, 0.004), Vec3::Zero(), f);
    return f;
  };
  const Vec3 plain = press(false), tilted = press(true);
  EXPECT_NEAR(plain.norm(), tilted.norm(), 1e-9) << "the tilt turns the force, not its size";
  EXPECT_GT((plain.normalized() - tilted.normalized()).norm(), 0.01);
}

TEST(TissueSurfaceTest, ABrokenOrHostileSurfaceIsRefusedByName) {
  const auto refused = [](SurfaceSpec s) {
    auto r = TissueSurface::Create(std::move(s));
    EXPECT_FALSE(r.ok());
    return r.ok() ? std::string() : r.error().field;
  };
  SurfaceSpec s = Sphere();
  s.triangles[0][1] = static_cast<int>(s.positions.size());
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.triangles[3][2] = -1;
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.positions[5].x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.stiffness[7] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.stiffness[7] = 1e9;
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.stiffness.pop_back();
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.damping = -1;
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.reach = 0;
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.reach = 5;
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();
  s.triangles.clear();
  EXPECT_EQ(refused(s), "surface");
  s = Sphere();  // a tissue curve that falls
  s.tissue_curve.count = 2;
  s.tissue_curve.yield = {1e-3, 2e-3};
  s.tissue_curve.force = {0.3, 0.2};
  EXPECT_EQ(refused(s), "surface");
  EXPECT_TRUE(TissueSurface::Create(Sphere()).ok());
  // A contact on no surface gives nothing.
  SurfaceContact none(nullptr);
  Vec3 f;
  EXPECT_FALSE(none.Render(Vec3::Zero(), Vec3::Zero(), f));
}

}  // namespace
}  // namespace vsurg::haptics
