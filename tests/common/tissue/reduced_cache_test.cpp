#include "common/tissue/reduced_cache.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/geometry/tet_generators.h"
#include "tests/support/temp_dir.h"

namespace vsurg::tissue::reduced_cache_test {
namespace {

namespace fs = std::filesystem;
using Vec3 = Eigen::Vector3d;

class ReducedCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto c = geometry::MakeTetCylinder({0.1, 0.01, 0.01, 2, 8});
    ASSERT_TRUE(c.ok());
    twist_.mesh = c->mesh;
    twist_.material.young = 2 * 12000 * 1.45;
    twist_.material.poisson = 0.45;
    twist_.fixed = c->base;
    twist_.face = c->tip;
    twist_.face_area = c->tip_area;
    twist_.display = c->mesh.positions;
  }

  std::string File() const { return (dir_ / "bar.vrm").string(); }
  std::string Contents() const {
    std::ifstream in(File(), std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  void Overwrite(const std::string& s) const {
    std::ofstream out(File(), std::ios::binary | std::ios::trunc);
    out << s;
  }

  test::TempDir dir_{"reduced_cache"};
  TwistFieldInputs twist_;
};

TEST_F(ReducedCacheTest, MissThenHitGivesTheSameField) {
  ReducedCache cache(dir_.string());
  CacheReport r;
  auto first = cache.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ(r.outcome, CacheOutcome::kMiss);
  EXPECT_GT(r.compute_s, 0);
  EXPECT_TRUE(fs::exists(File()));
  auto second = cache.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kHit) << r.message;
  EXPECT_EQ(r.compute_s, 0);
  EXPECT_EQ(first->angle, second->angle);
  EXPECT_EQ(first->warp, second->warp);
  EXPECT_EQ(first->radial, second->radial);
  EXPECT_EQ(first->lateral, second->lateral);
  EXPECT_EQ(first->grasp_compliance, second->grasp_compliance);
}

// The hyperelastic twist's table of load levels: cached like the field, its law in the key.
TEST_F(ReducedCacheTest, ATwistTableIsCachedAndItsLawIsInTheKey) {
  ReducedCache cache(dir_.string());
  TwistTableInputs in;
  in.mesh = twist_.mesh;
  in.material = {twist_.material.young, twist_.material.poisson, 0, false};
  in.fixed = twist_.fixed;
  in.face = twist_.face;
  in.display = twist_.display;
  in.max_twist = 0.8;
  in.levels = 2;
  CacheReport r;
  auto first = cache.TwistTableFor("bar", in, &r);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ(r.outcome, CacheOutcome::kMiss);
  auto second = cache.TwistTableFor("bar", in, &r);
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kHit) << r.message;
  EXPECT_EQ(first->torque, second->torque);
  EXPECT_EQ(first->angle, second->angle);
  EXPECT_EQ(first->lateral, second->lateral);
  in.material.stiffening = 3;  // the exponential law: another table, stiffer at the ends
  auto stiffer = cache.TwistTableFor("bar", in, &r);
  ASSERT_TRUE(stiffer.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kStale);
  EXPECT_GT(stiffer->torque.back(), first->torque.back());
  const std::string whole = Contents();
  Overwrite(whole.substr(0, whole.size() - 8));
  ASSERT_TRUE(cache.TwistTableFor("bar", in, &r).ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kCorrupt);
}

TEST_F(ReducedCacheTest, AChangedMaterialOrMeshIsStaleAndRebuilt) {
  ReducedCache cache(dir_.string());
  CacheReport r;
  auto soft = cache.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(soft.ok());
  twist_.material.young *= 2;  // twice as stiff: half the twist
  auto stiff = cache.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(stiff.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kStale);
  EXPECT_NE(r.message.find("bar.vrm"), std::string::npos) << r.message;
  EXPECT_NEAR(stiff->grasp_compliance, 0.5 * soft->grasp_compliance, 1e-9 * soft->grasp_compliance);
  // The rebuilt file now answers for the new material.
  ASSERT_TRUE(cache.TwistFieldFor("bar", twist_, &r).ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kHit);
  twist_.mesh.positions[3].z() += 1e-4;  // one vertex moved
  ASSERT_TRUE(cache.TwistFieldFor("bar", twist_, &r).ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kStale);
}

TEST_F(ReducedCacheTest, TruncatedTamperedOrForeignFilesAreRebuiltNeverUsed) {
  ReducedCache cache(dir_.string());
  CacheReport r;
  auto good = cache.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(good.ok());
  const std::string whole = Contents();
  struct Case {
    const char* what;
    std::string bytes;
  };
  std::string tampered = whole;
  tampered[tampered.size() / 2] ^= 0x10;  // one bit of the payload
  std::string tampered_size = whole;      // a payload size that reads past the end
  tampered_size[40] ^= 0x01;
  const std::vector<Case> cases = {
      {"truncated", whole.substr(0, whole.size() - 100)},
      {"tampered", tampered},
      {"size", tampered_size},
      {"header only", whole.substr(0, 20)},
      {"empty", ""},
      {"foreign", "solid cube\nendsolid\n"},
  };
  for (const Case& c : cases) {
    Overwrite(c.bytes);
    auto again = cache.TwistFieldFor("bar", twist_, &r);
    ASSERT_TRUE(again.ok()) << c.what;
    EXPECT_EQ(r.outcome, CacheOutcome::kCorrupt) << c.what;
    EXPECT_FALSE(r.message.empty()) << c.what;
    EXPECT_EQ(again->angle, good->angle) << c.what;  // recomputed, not read
    EXPECT_EQ(Contents(), whole) << c.what;          // and rewritten whole
  }
}

TEST_F(ReducedCacheTest, ContactTablesRoundTripAndBadNamesOrDirsAreReported) {
  auto ball = geometry::MakeTetBall({0.05, 2});
  ASSERT_TRUE(ball.ok());
  ContactInputs in;
  in.mesh = *ball;
  in.material = twist_.material;
  in.display = geometry::BoundarySurface(*ball);
  for (int i = 0; i < ball->VertexCount(); ++i) {
    if (ball->positions[i].z() < -0.03) in.fixed.push_back(i);
    if (ball->positions[i].z() > 0.03) in.reachable.push_back(i);
  }
  ReducedCache cache(dir_.string());
  CacheReport r;
  auto first = cache.ContactResponseFor("ball", in, &r);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ(r.outcome, CacheOutcome::kMiss);
  auto second = cache.ContactResponseFor("ball", in, &r);
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kHit);
  EXPECT_EQ(first->g, second->g);
  EXPECT_EQ(first->w.size(), first->g.size());  // the rotation responses are cached too
  EXPECT_EQ(first->w, second->w);
  EXPECT_EQ(first->contacts, second->contacts);
  EXPECT_EQ(first->slot_of_vertex, second->slot_of_vertex);
  in.params.footprint_radius *= 2;
  ASSERT_TRUE(cache.ContactResponseFor("ball", in, &r).ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kStale);
  // A name that would leave the folder is refused; a folder that cannot be written still
  // gives the result, and says it was not cached.
  EXPECT_FALSE(cache.ContactResponseFor("../ball", in, &r).ok());
  EXPECT_FALSE(cache.TwistFieldFor("", twist_, &r).ok());
  { std::ofstream blocker(dir_ / "file"); }
  ReducedCache blocked((dir_ / "file" / "sub").string());
  auto uncached = blocked.TwistFieldFor("bar", twist_, &r);
  ASSERT_TRUE(uncached.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kUnwritable);
  EXPECT_NE(r.message.find("not cached"), std::string::npos) << r.message;
}

TEST_F(ReducedCacheTest, SurfaceTwistTablesRoundTripAndGoStaleWithTheJaws) {
  auto ball = geometry::MakeTetBall({0.05, 4});
  ASSERT_TRUE(ball.ok());
  SurfaceTwistInputs in;
  in.mesh = *ball;
  in.material = twist_.material;
  in.display = geometry::BoundarySurface(*ball);
  for (int i = 0; i < ball->VertexCount(); ++i) {
    if (ball->positions[i].z() < -0.03) in.fixed.push_back(i);
    if (ball->positions[i].z() > 0.03 && ball->positions[i].norm() > 0.049)
      in.reachable.push_back(i);
  }
  in.params.jaw_radius = 0.015;
  ReducedCache cache(dir_.string());
  CacheReport r;
  auto first = cache.SurfaceTwistFor("bar", in, &r);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ(r.outcome, CacheOutcome::kMiss);
  auto second = cache.SurfaceTwistFor("bar", in, &r);
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kHit);
  EXPECT_EQ(first->angle, second->angle);
  EXPECT_EQ(first->grasp_compliance, second->grasp_compliance);
  EXPECT_EQ(first->axis, second->axis);
  EXPECT_EQ(first->grasps, second->grasps);
  // A tampered payload is rebuilt, never used.
  std::string bytes = Contents();
  bytes[bytes.size() / 2] ^= 0x10;
  Overwrite(bytes);
  auto third = cache.SurfaceTwistFor("bar", in, &r);
  ASSERT_TRUE(third.ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kCorrupt);
  EXPECT_EQ(third->angle, first->angle);
  // Other jaws: another load, stale.
  in.params.jaw_radius = 0.02;
  ASSERT_TRUE(cache.SurfaceTwistFor("bar", in, &r).ok());
  EXPECT_EQ(r.outcome, CacheOutcome::kStale);
}

}  // namespace
}  // namespace vsurg::tissue::reduced_cache_test
