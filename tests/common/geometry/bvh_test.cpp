#include "common/geometry/bvh.h"

#include <algorithm>
#include <cstdint>
#include <random>

#include <gtest/gtest.h>

#include "common/geometry/mesh_generators.h"

namespace vsurg::geometry {
namespace {

ClosestHit BruteClosest(const TriMesh& m, const Vec3& p) {
  ClosestHit best;
  for (int t = 0; t < m.TriangleCount(); ++t) {
    const auto& tri = m.triangles[t];
    const Vec3 w =
        ClosestPointOnTriangle(p, m.positions[tri[0]], m.positions[tri[1]], m.positions[tri[2]]);
    const Vec3 q =
        w[0] * m.positions[tri[0]] + w[1] * m.positions[tri[1]] + w[2] * m.positions[tri[2]];
    if ((q - p).norm() < best.distance) best = ClosestHit{t, w, q, (q - p).norm()};
  }
  return best;
}

double BruteFirstHit(const TriMesh& m, const Vec3& a, const Vec3& b) {
  double best = 2;
  const Vec3 d = b - a;
  for (const auto& tri : m.triangles) {
    const Vec3 p0 = m.positions[tri[0]], e1 = m.positions[tri[1]] - p0,
               e2 = m.positions[tri[2]] - p0;
    const Vec3 n = e1.cross(e2);
    const double denom = n.dot(d);
    if (std::abs(denom) < 1e-300) continue;
    const double t = n.dot(p0 - a) / denom;
    if (t < 0 || t > 1) continue;
    const Vec3 q = a + t * d - p0;
    // Barycentric of q in (e1, e2).
    const double d00 = e1.dot(e1), d01 = e1.dot(e2), d11 = e2.dot(e2), d20 = q.dot(e1),
                 d21 = q.dot(e2);
    const double den = d00 * d11 - d01 * d01;
    const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    if (v >= 0 && w >= 0 && v + w <= 1) best = std::min(best, t);
  }
  return best;
}

// 400 random points and segments around the limb: the tree's closest points and first hits
// against brute force over every triangle.
void ExpectAnswersAsBruteForce(const Bvh& bvh, const TriMesh& m, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.06, 0.06), z(-0.05, 0.3);
  for (int q = 0; q < 400; ++q) {
    const Vec3 p(u(rng), u(rng), z(rng));
    const ClosestHit fast = bvh.Closest(m.positions, p);
    const ClosestHit slow = BruteClosest(m, p);
    ASSERT_GE(fast.triangle, 0);
    EXPECT_NEAR(fast.distance, slow.distance, 1e-12) << q;
    const Vec3 b(u(rng), u(rng), z(rng));
    const RayHit hit = bvh.FirstHit(m.positions, p, b);
    const double brute = BruteFirstHit(m, p, b);
    if (brute <= 1) {
      ASSERT_GE(hit.triangle, 0) << q;
      EXPECT_NEAR(hit.t, brute, 1e-9) << q;
    } else {
      EXPECT_EQ(hit.triangle, -1) << q;
    }
  }
}

TEST(BvhTest, ClosestPointAndFirstHitMatchBruteForceOnRandomQueries) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  // Deform it a little so the refit is exercised, then refit.
  Bvh bvh(m);
  for (Vec3& p : m.positions)
    p += Vec3(0.005 * std::sin(40 * p.z()), 0.003 * std::cos(30 * p.z()), 0);
  bvh.Refit(m.positions);
  ASSERT_NO_FATAL_FAILURE(ExpectAnswersAsBruteForce(bvh, m, 5));
}

// A refit after a large motion (the limb twisted a quarter turn at its far end and bent aside): a
// box that missed one of its leaf's corners would hide the true closest point from the queries.
TEST(BvhTest, ARefitAfterATwistAnswersAsBruteForce) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  Bvh bvh(m);
  for (Vec3& p : m.positions) {
    const double a = 1.57 * std::clamp(p.z() / 0.25, 0.0, 1.0);
    p = Vec3(std::cos(a) * p.x() - std::sin(a) * p.y() + 0.2 * p.z() * p.z(),
             std::sin(a) * p.x() + std::cos(a) * p.y(), p.z());
  }
  bvh.Refit(m.positions);
  ASSERT_NO_FATAL_FAILURE(ExpectAnswersAsBruteForce(bvh, m, 11));
}

TEST(BvhTest, FrontFaceMeansEnteringAndTheNormalFilterSkipsFacesTurnedAway) {
  auto sphere = MakeSubdividedSphere({0.05, 3, SphereBase::kOctahedron});
  Bvh bvh(*sphere);
  const RayHit in = bvh.FirstHit(sphere->positions, Vec3(0.001, 0.002, 0.1), Vec3(0.001, 0.002, 0));
  ASSERT_GE(in.triangle, 0);
  EXPECT_TRUE(in.front_face);
  const RayHit out =
      bvh.FirstHit(sphere->positions, Vec3(0.001, 0.002, 0), Vec3(0.001, 0.002, 0.1));
  ASSERT_GE(out.triangle, 0);
  EXPECT_FALSE(out.front_face);
  // From just under the north pole, the closest face is on top; asking only for faces whose
  // normal points down (n_z ≤ −0.5) finds the nearest of those, below latitude −30°.
  const ClosestHit top = bvh.Closest(sphere->positions, Vec3(0, 0, 0.045));
  EXPECT_GT(top.point.z(), 0.04);
  const ClosestHit down =
      bvh.Closest(sphere->positions, Vec3(0, 0, 0.045), INFINITY, Vec3(0, 0, -1), 0.5);
  ASSERT_GE(down.triangle, 0);
  EXPECT_LE(TriangleNormal(*sphere, down.triangle).z(), -0.5);
  EXPECT_LT(down.point.z(), -0.015);
  // A range limit: nothing within 1 mm of the centre.
  EXPECT_EQ(bvh.Closest(sphere->positions, Vec3::Zero(), 0.001).triangle, -1);
  EXPECT_EQ(bvh.Closest(sphere->positions, Vec3(NAN, 0, 0)).triangle, -1);
}

// A start face only bounds the search: the answer's distance is the brute force's whatever the
// start (the last answer, any face, none, one out of range, one the normal filter refuses), and
// a start beyond the range or turned away is never the answer.
TEST(BvhTest, AStartTriangleNeverChangesTheClosestDistance) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  Bvh bvh(m);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.06, 0.06), z(-0.05, 0.3);
  std::uniform_int_distribution<int> face(-2, m.TriangleCount() + 2);
  int last = -1;
  Vec3 p(0.01, 0.0, 0.1);
  for (int q = 0; q < 600; ++q) {
    // Half the queries walk (the haptic loop's case, starting from the last answer), half jump.
    p = q % 2 ? Vec3(p + Vec3(0.002 * u(rng), 0.002 * u(rng), 0.002 * u(rng)))
              : Vec3(u(rng), u(rng), z(rng));
    const int start = q % 3 == 0 ? face(rng) : last;
    const ClosestHit slow = BruteClosest(m, p);
    const ClosestHit fast = bvh.Closest(m.positions, p, INFINITY, Vec3::Zero(), -2.0, start);
    ASSERT_GE(fast.triangle, 0) << q;
    EXPECT_NEAR(fast.distance, slow.distance, 1e-12) << q;
    last = fast.triangle;
    // Within a range the start is farther than: nothing, or something nearer than the range.
    const double range = 0.5 * slow.distance;
    EXPECT_EQ(bvh.Closest(m.positions, p, range, Vec3::Zero(), -2.0, last).triangle, -1) << q;
    // A start the filter refuses is not the answer; the answer is the filtered brute force's.
    const Vec3 hint = TriangleNormal(m, last);
    const ClosestHit away = bvh.Closest(m.positions, p, INFINITY, -hint, 0.5, last);
    ASSERT_NE(away.triangle, last) << q;
    const ClosestHit away_cold = bvh.Closest(m.positions, p, INFINITY, -hint, 0.5);
    EXPECT_NEAR(away.distance, away_cold.distance, 1e-12) << q;
  }
}

// The kept list answers as the tree does: a tip walking under a surface that moves a little every
// third call (drifting, each vertex also at random; the motion reported as the largest move), with
// the proxy's normal filter and start face, ranges that sometimes hold nothing, and jumps. The list
// must answer most calls of a slow walk (else it is not kept at all) and never change a distance.
TEST(ClosestCacheTest, TheKeptListAnswersAsTheTreeDoesOverAMovingSurface) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  Bvh bvh(m);
  ClosestCache cache(1e-3);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), unit(0, 1);
  Vec3 p(0.03, 0.0, 0.1), drift = Vec3::Zero();
  double motion = 0;
  int start = -1, answered = 0;
  for (int q = 0; q < 3000; ++q) {
    // Mostly a walk of 20–200 µm a call; every 250th call a jump to within 5 mm of a face.
    if (q % 250 == 0 || q % 500 == 100) {
      const int t = static_cast<int>(unit(rng) * (m.TriangleCount() - 1));
      const auto& tri = m.triangles[t];
      p = (m.positions[tri[0]] + m.positions[tri[1]] + m.positions[tri[2]]) / 3.0 +
          0.005 * u(rng) * TriangleNormal(m, t);
    } else if (q % 500 >= 100) {  // the first 100 of every 500 the tip rests
      p += (20e-6 + 180e-6 * unit(rng)) * Vec3(u(rng), u(rng), u(rng));
    }
    // Every third call the surface moves: 150 µm one way (a new way every 100 calls: the tissue
    // under a resting tip slides 5 mm, beyond the list's reach) and up to 10 µm at random per
    // vertex.
    if (q % 100 == 0) drift = 150e-6 * Vec3(u(rng), u(rng), u(rng)).normalized();
    if (q % 3 == 0) {
      double largest = 0;
      for (Vec3& x : m.positions) {
        const Vec3 d = drift + 10e-6 / std::sqrt(3.0) * Vec3(u(rng), u(rng), u(rng));
        x += d;
        largest = std::max(largest, d.norm());
      }
      bvh.Refit(m.positions);
      motion += largest;
    }
    const bool filtered = q % 2 == 0 && start >= 0;
    const Vec3 hint = filtered ? TriangleNormal(m, start) : Vec3::Zero();
    const double range = q % 7 == 0 ? 0.002 : 0.02;
    const ClosestHit tree = bvh.Closest(m.positions, p, range, hint, filtered ? 0.0 : -2.0, start);
    const ClosestHit kept =
        cache.Closest(bvh, m.positions, motion, p, range, hint, filtered ? 0.0 : -2.0, start);
    ASSERT_EQ(kept.triangle >= 0, tree.triangle >= 0) << q;
    if (tree.triangle < 0) continue;
    ++answered;
    EXPECT_NEAR(kept.distance, tree.distance, 1e-12) << q;
    // The face returned is as near as it says, and passes the filter.
    const auto& t = m.triangles[kept.triangle];
    const Vec3 w =
        ClosestPointOnTriangle(p, m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]);
    const Vec3 on = w[0] * m.positions[t[0]] + w[1] * m.positions[t[1]] + w[2] * m.positions[t[2]];
    EXPECT_NEAR((on - p).norm(), kept.distance, 1e-12) << q;
    if (filtered) {
      EXPECT_GE(TriangleNormal(m, kept.triangle).dot(hint), -1e-12) << q;
    }
    start = kept.triangle;
  }
  EXPECT_GT(answered, 1000);
  EXPECT_EQ(cache.hits() + cache.misses(), 3000u);
  EXPECT_GT(cache.hits(), 2000u) << "the list answered " << cache.hits() << " of 3000";
}

// The list is nearest first, so an answer measures only the faces that could be nearer than its
// best so far: a tip resting 4 mm under the surface measures the face under it (and its equals),
// not the dozens listed around it; a tip that then walks 1 mm measures more, still not all, and
// answers as the tree does throughout.
TEST(ClosestCacheTest, AnAnswerMeasuresOnlyTheListedFacesThatCouldBeNearer) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  Bvh bvh(m);
  ClosestCache cache(1e-3);  // faces within the answer's distance + 2 mm are listed
  const int t0 = m.TriangleCount() / 3;
  const auto& tri = m.triangles[t0];
  const Vec3 under = (m.positions[tri[0]] + m.positions[tri[1]] + m.positions[tri[2]]) / 3.0 -
                     0.004 * TriangleNormal(m, t0);
  const ClosestHit first = cache.Closest(bvh, m.positions, 0.0, under, 0.02);
  ASSERT_GE(first.triangle, 0);
  ASSERT_EQ(cache.misses(), 1u);
  const size_t listed = cache.listed();
  ASSERT_GE(listed, 8u) << "a list this short tests nothing";
  for (int k = 0; k < 100; ++k) {
    const ClosestHit again = cache.Closest(bvh, m.positions, 0.0, under, 0.02);
    ASSERT_EQ(again.distance, first.distance);
  }
  ASSERT_EQ(cache.hits(), 100u);
  EXPECT_LE(cache.examined(), 100u * 3) << "of " << listed << " listed";
  // Walking 1 mm across the face (10 µm a call): the bound loosens as the tip leaves the list's
  // centre, so more is measured, but never more than listed, and the answers stay the tree's.
  const Vec3 across = TriangleNormal(m, t0).unitOrthogonal();
  const uint64_t examined_resting = cache.examined(), hits_resting = cache.hits();
  for (int k = 1; k <= 100; ++k) {
    const Vec3 p = under + 1e-5 * k * across;
    EXPECT_NEAR(cache.Closest(bvh, m.positions, 0.0, p, 0.02).distance,
                bvh.Closest(m.positions, p, 0.02).distance, 1e-12)
        << k;
  }
  const uint64_t walked = cache.hits() - hits_resting;
  ASSERT_GT(walked, 50u);
  const double per_answer =
      static_cast<double>(cache.examined() - examined_resting) / static_cast<double>(walked);
  EXPECT_LT(per_answer, static_cast<double>(listed));
}

// The reported motion is what lets a face from off the list in: a face pushed towards the point
// by more than the margin is found when the motion says it moved (and with an unknown motion the
// tree answers every call).
TEST(ClosestCacheTest, AFaceThatMovedInIsFoundWhenTheMotionSaysSo) {
  TriMesh m = MakeLimb(WithResolution(ForearmPreset(), 1500))->surface;
  Bvh bvh(m);
  ClosestCache cache(1e-3);
  const auto& t0 = m.triangles[m.TriangleCount() / 2];
  const Vec3 p = (m.positions[t0[0]] + m.positions[t0[1]] + m.positions[t0[2]]) / 3.0 -
                 0.005 * TriangleNormal(m, m.TriangleCount() / 2);  // 5 mm under a face
  const ClosestHit first = cache.Closest(bvh, m.positions, 0.0, p, INFINITY);
  ASSERT_GE(first.triangle, 0);
  EXPECT_EQ(cache.Closest(bvh, m.positions, 0.0, p, INFINITY).distance, first.distance);
  EXPECT_EQ(cache.hits(), 1u);
  // The farthest face from p, moved to 0.1 mm from it (its three corners dragged there).
  int far = 0;
  double far_d = 0;
  for (int t = 0; t < m.TriangleCount(); ++t) {
    const double d = (m.positions[m.triangles[t][0]] - p).norm();
    if (d > far_d) {
      far_d = d;
      far = t;
    }
  }
  double largest = 0;
  for (int v : m.triangles[far]) {
    const Vec3 to = p + 1e-4 * Vec3(1, 0, 0) + 1e-5 * Vec3::Random();
    largest = std::max(largest, (to - m.positions[v]).norm());
    m.positions[v] = to;
  }
  bvh.Refit(m.positions);
  ASSERT_GT(first.distance, 1e-3);  // a list kept past the move would answer this
  const ClosestHit moved = cache.Closest(bvh, m.positions, largest, p, INFINITY);
  EXPECT_LT(moved.distance, 2e-4);  // the moved face, or a neighbour dragged with it
  EXPECT_NEAR(moved.distance, bvh.Closest(m.positions, p).distance, 1e-15);
  EXPECT_EQ(cache.hits(), 1u);  // the tree answered
  ClosestCache unknown(1e-3);
  for (int k = 0; k < 3; ++k) unknown.Closest(bvh, m.positions, INFINITY, p, INFINITY);
  EXPECT_EQ(unknown.hits(), 0u);
  EXPECT_EQ(unknown.misses(), 3u);
}

}  // namespace
}  // namespace vsurg::geometry
