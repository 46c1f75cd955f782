#include "common/geometry/tet_embedding.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "common/geometry/tet_generators.h"

namespace vsurg::geometry {
namespace {

TEST(TetEmbeddingTest, InsidePointsReproduceALinearFieldExactly) {
  auto ball = MakeTetBall({0.05, 6});
  ASSERT_TRUE(ball.ok());
  // u(x) = A·x + b sampled at the vertices; linear elements interpolate it exactly.
  Eigen::Matrix3d a;
  a << 1, 2, -3, 0.5, -1, 4, 2, 0, 1;
  const Vec3 b(0.1, -0.2, 0.3);
  std::vector<Vec3> field;
  for (const Vec3& x : ball->positions) field.push_back(a * x + b);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.03, 0.03);  // inside the ball (|x| < 0.052)
  std::vector<Vec3> points;
  for (int i = 0; i < 500; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  auto e = EmbedPoints(*ball, points);
  ASSERT_TRUE(e.ok()) << e.error().message;
  for (size_t i = 0; i < points.size(); ++i) {
    const EmbeddedPoint& p = (*e)[i];
    EXPECT_EQ(p.distance, 0.0) << i;
    double sum = 0;
    for (double w : p.weights) {
      EXPECT_GE(w, 0.0);
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_LT((Interpolate(p, field) - (a * points[i] + b)).norm(), 1e-12) << i;
  }
}

TEST(TetEmbeddingTest, OutsidePointsGetTheNearestElementAndTheirDistance) {
  // A bar of radius 1 cm along z; points 2 mm and 3 cm outside its side, and beyond its tip.
  auto bar = MakeTetCylinder({0.2, 0.01, 0.01, 2, 10});
  ASSERT_TRUE(bar.ok());
  const std::vector<Vec3> points = {{0.012, 0, 0.1}, {0, 0.04, 0.05}, {0, 0, 0.25}};
  auto e = EmbedPoints(bar->mesh, points);
  ASSERT_TRUE(e.ok());
  // The faceted side is within 1 − cos(30°) of the radius inside the circle.
  EXPECT_NEAR((*e)[0].distance, 0.002, 0.0015);
  EXPECT_NEAR((*e)[1].distance, 0.03, 0.0015);
  EXPECT_NEAR((*e)[2].distance, 0.05, 1e-9);
  // The nearest point of the tip element lies on the tip face (z = 0.2).
  Vec3 nearest = Vec3::Zero();
  for (int k = 0; k < 4; ++k)
    nearest += (*e)[2].weights[k] * bar->mesh.positions[(*e)[2].vertices[k]];
  EXPECT_NEAR(nearest.z(), 0.2, 1e-12);
}

TEST(TetEmbeddingTest, BadInputIsRefused) {
  auto ball = MakeTetBall({0.05, 2});
  ASSERT_TRUE(ball.ok());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto e = EmbedPoints(*ball, {Vec3(0, 0, 0), Vec3(nan, 0, 0)});
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("point 1"), std::string::npos) << e.error().message;
  EXPECT_FALSE(EmbedPoints(TetMesh{}, {Vec3::Zero()}).ok());
}

}  // namespace
}  // namespace vsurg::geometry
