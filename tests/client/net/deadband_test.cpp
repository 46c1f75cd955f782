#include "client/net/deadband.h"

#include <algorithm>
#include <vector>

#include <gtest/gtest.h>

namespace vsurg::client {
namespace {

constexpr double kCycleS = 0.001;  // s, one servo cycle

haptics::StylusSample StillAt(double z) {
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0, 0, z);
  return s;
}

// Sends over cycles [from, to) of a hand resting at z with force f(cycle).
template <typename F>
int Sends(Deadband& d, int from, int to, double z, F force, std::vector<int>* which = nullptr) {
  int n = 0;
  for (int c = from; c < to; ++c) {
    if (d.Due(c * kCycleS, StillAt(z), force(c))) {
      ++n;
      if (which) which->push_back(c);
    }
  }
  return n;
}

TEST(DeadbandTest, AStillHandSendsOnlyHeartbeats) {
  Deadband d({.k = 0.1});
  const Eigen::Vector3d f(0, 0, 0.4);
  EXPECT_TRUE(d.Due(0, StillAt(0), Eigen::Vector3d::Zero()));  // the first sample always goes
  // Free space, still: one per heartbeat (25 ms, a cycle later where the clock's sum rounds
  // under it).
  const int free = Sends(d, 1, 1001, 0, [](int) { return Eigen::Vector3d::Zero(); });
  EXPECT_GE(free, 38);
  EXPECT_LE(free, 40);
  // A steady 0.4 N after the contact's start: every cycle for 50 ms, then heartbeats alone.
  std::vector<int> sent;
  Sends(
      d, 1001, 2001, 0, [&](int) { return f; }, &sent);
  ASSERT_GE(sent.size(), 50u);
  for (int c = 1001; c < 1050; ++c) EXPECT_EQ(sent[c - 1001], c);
  const int after =
      static_cast<int>(std::count_if(sent.begin(), sent.end(), [](int c) { return c >= 1051; }));
  EXPECT_GE(after, 37);
  EXPECT_LE(after, 39);
}

TEST(DeadbandTest, APerceptibleChangeIsSentAndRepeatedOnce) {
  Deadband d({.k = 0.1, .onset_s = 0});
  const Eigen::Vector3d f(0, 0, 0.4);
  EXPECT_TRUE(d.Due(0, StillAt(0), f));
  // 0.4 N → 0.43 N: under 10% + 0.02 N, not sent until the heartbeat.
  EXPECT_EQ(Sends(d, 1, 20, 0, [&](int) { return Eigen::Vector3d(0, 0, 0.43); }), 0);
  // → 0.47 N: sent at once, and once more 5 ms later (a lost datagram costs 5 ms).
  std::vector<int> sent;
  Sends(
      d, 20, 24, 0, [&](int) { return Eigen::Vector3d(0, 0, 0.47); }, &sent);
  EXPECT_EQ(sent, std::vector<int>{20});
  EXPECT_EQ(Sends(
                d, 24, 26, 0, [&](int) { return Eigen::Vector3d(0, 0, 0.47); }, &sent),
            1);
  EXPECT_EQ(sent.back(), 25);
  // The tip moving 0.6 mm is sent whatever the force.
  EXPECT_TRUE(d.Due(0.030, StillAt(0.0006), Eigen::Vector3d(0, 0, 0.47)));
}

TEST(DeadbandTest, EachContactStartsAtFullRateAndZeroKSendsEveryCycle) {
  Deadband d({.k = 0.1, .onset_s = 0.02});
  auto touch = [](int c) {
    // Two touches of 100 ms, 100 ms apart.
    const bool in = (c >= 100 && c < 200) || (c >= 300 && c < 400);
    return Eigen::Vector3d(0, 0, in ? 0.3 : 0.0);
  };
  std::vector<int> sent;
  Sends(d, 0, 500, 0, touch, &sent);
  for (int start : {100, 300}) {
    for (int c = start; c < start + 20; ++c)
      EXPECT_NE(std::find(sent.begin(), sent.end(), c), sent.end()) << c;
    EXPECT_LE(std::count_if(sent.begin(), sent.end(),
                            [&](int c) { return c >= start + 21 && c < start + 100; }),
              5);
  }
  Deadband every({.k = 0});
  EXPECT_EQ(Sends(every, 0, 100, 0, touch), 100);
}

// While a force is rendered the heartbeat is the contact's (the server's tissue is driven by the
// samples it gets); in free space it is the slower one. A contact heartbeat above the free one is
// the free one.
TEST(DeadbandTest, ARenderedForceKeepsItsOwnHeartbeat) {
  Deadband d({.k = 0.1, .onset_s = 0, .heartbeat_s = 0.025, .contact_heartbeat_s = 0.010});
  const Eigen::Vector3d f(0, 0, 0.4);
  EXPECT_TRUE(d.Due(0, StillAt(0), Eigen::Vector3d::Zero()));
  const int free = Sends(d, 1, 1001, 0, [](int) { return Eigen::Vector3d::Zero(); });
  EXPECT_GE(free, 38);
  EXPECT_LE(free, 40);
  // A steady force: the first change is sent (and repeated once), then every 10 ms.
  const int touching = Sends(d, 1001, 2001, 0, [&](int) { return f; });
  EXPECT_GE(touching, 98);
  EXPECT_LE(touching, 102);
  Deadband capped({.k = 0.1, .onset_s = 0, .heartbeat_s = 0.025, .contact_heartbeat_s = 0.1});
  EXPECT_TRUE(capped.Due(0, StillAt(0), f));
  const int held = Sends(capped, 1, 1001, 0, [&](int) { return f; });
  EXPECT_GE(held, 38);
  EXPECT_LE(held, 40);
}

}  // namespace
}  // namespace vsurg::client
