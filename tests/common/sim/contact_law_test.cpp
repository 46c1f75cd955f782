// The contact's tissue law measured on the server's tissue (common/sim/contact_law.h), and what
// a station's surface carries of it.
#include "common/sim/contact_law.h"

#include <gtest/gtest.h>

#include "common/sim/simulation.h"

namespace vsurg::sim {
namespace {

// The shipped ball's law is the one measured now: the fit at the good trainee's press and the
// static curve, point by point (a change in the tissue's physics that moves it asks for the scene
// to be measured again). The curve rises from (0, 0) and its secant at the tap's 2.4 mm of yield
// is well above the tangent k_t, the ball's surface yielding stiffly first.
TEST(ContactLawTest, TheBallsLawIsTheOneItsSceneCarries) {
  auto scene = LoadSceneByName("sphere-palpation-256");
  ASSERT_TRUE(scene.ok());
  auto law = MeasureContactLaw(*scene);
  ASSERT_TRUE(law.ok()) << law.error().message;
  EXPECT_NEAR(law->stiffness, scene->haptics.tissue_stiffness, 0.01 * law->stiffness);
  EXPECT_NEAR(law->damping, scene->haptics.tissue_damping, 0.01 * law->damping);
  const haptics::TissueCurve& shipped = scene->haptics.tissue_curve;
  ASSERT_EQ(law->tissue.count, shipped.count);
  ASSERT_TRUE(law->tissue.Valid());
  for (int i = 0; i < shipped.count; ++i) {
    EXPECT_NEAR(law->tissue.yield[i], shipped.yield[i], 0.01 * shipped.yield[i]) << i;
    EXPECT_NEAR(law->tissue.force[i], shipped.force[i], 0.01 * shipped.force[i]) << i;
  }
  // Each point settled: the proxy's spring holds it, f = k_p·(d − S).
  const double kp = scene->haptics.proxy.stiffness;
  for (const auto& p : law->curve)
    EXPECT_NEAR(p.force, kp * (p.depth - p.yield), 0.02 * p.force) << p.depth;
  EXPECT_GT(shipped.Elastic(2.4e-3) / 2.4e-3, 1.3 * law->stiffness);
}

// The station's surface carries the scene's curve (the ball's; the ring layer's is nearly a line
// and keeps k_t), and says whether its faces tilt as their corners yield: a mass-spring surface's
// contact loads the corners, the ring layer centres its rings on the contact point. A scene that
// is not a press is refused by name.
TEST(ContactLawTest, TheStationsSurfaceCarriesTheCurveAndHowItsFacesYield) {
  for (const auto& [name, corners] :
       {std::pair{"sphere-palpation-256", true}, std::pair{"sphere-palpation-rings", false}}) {
    auto scene = LoadSceneByName(name);
    ASSERT_TRUE(scene.ok());
    auto simulation = Simulation::Create(*scene, {.threaded = false});
    ASSERT_TRUE(simulation.ok());
    const auto surface = (*simulation)->station_surface();
    ASSERT_TRUE(surface);
    EXPECT_EQ(surface->spec().corners_yield, corners) << name;
    EXPECT_EQ(surface->spec().tissue_curve.count, scene->haptics.tissue_curve.count) << name;
    EXPECT_EQ(surface->spec().tissue_curve.count > 0, corners) << name << ": the ball's only";
  }
  auto twist = LoadSceneByName("arm-torsion");
  ASSERT_TRUE(twist.ok());
  auto refused = MeasureContactLaw(*twist);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().field, "scene");
}

}  // namespace
}  // namespace vsurg::sim
