#include "client/net/passivity.h"

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace vsurg::client {
namespace {

constexpr double kDt = 1e-3;

// A hand moving along x by `motion(i)`, and an environment giving force(x) sampled at each cycle
// and held (zero-order hold) until the next: the energy the held forces really gave the hand,
// Σ F_k·(x_{k+1} − x_k), and the lowest the environment's balance ever fell.
template <class Motion, class Force>
double EnergyIntoHand(PassivityController* pc, Motion motion, Force force, int cycles,
                      double* lowest = nullptr) {
  double into_hand = 0, low = 0;
  Eigen::Vector3d held = Eigen::Vector3d::Zero();
  double x_prev = motion(0);
  for (int i = 0; i <= cycles; ++i) {
    const double x = motion(i);
    into_hand += held.x() * (x - x_prev);
    low = std::min(low, -into_hand);
    Eigen::Vector3d f(force(x), 0, 0);
    if (pc) f = pc->Apply(f, Eigen::Vector3d(x, 0, 0), kDt);
    held = f;
    x_prev = x;
  }
  if (lowest) *lowest = low;
  return into_hand;
}

TEST(PassivityTest, TheObserverPairsTheHeldForceWithTheMotionAfterIt) {
  // A stiff spring sampled at 1 kHz against an 8 Hz tremor: held over each interval, F = −k·x_k
  // gives the hand k·Δx²/2 per cycle (Colgate & Schenkel 1997), so the rendering is active. An
  // observer that paired F_k with the step into x_k read +k·Δx²/2: absorbing, and never acted.
  PassivityController observer(0.0);  // observe only
  const double k = 700;
  const auto tremor = [](int i) { return 0.001 * std::sin(2 * M_PI * 8 * i * kDt); };
  const double into_hand = EnergyIntoHand(
      &observer, tremor, [k](double x) { return -k * x; }, 4000);
  EXPECT_GT(into_hand, 0);                            // the sampled spring is active ...
  EXPECT_NEAR(observer.energy(), -into_hand, 1e-12);  // ... and the observer says exactly that
  EXPECT_LT(observer.energy(), 0);
  EXPECT_NEAR(observer.to_hand() - observer.from_hand(), into_hand, 1e-12);
}

TEST(PassivityTest, AnActiveEnvironmentIsMadePassive) {
  // A "spring" pushing away from the origin, F = +k x, gives the hand k·x²/2 = 10 mJ on every
  // outward stroke. The controller dissipates the excess as it appears; what is left is what its
  // damping cap and the turning points (v ≈ 0, nothing to damp) let through.
  const auto stroke = [](int i) { return 0.01 * std::sin(2 * M_PI * 2 * i * kDt); };
  const auto push = [](double x) { return 200 * x; };
  double lowest_free = 0, lowest_controlled = 0;
  EnergyIntoHand(nullptr, stroke, push, 5000, &lowest_free);
  PassivityController pc(50.0, 0.0);
  const double controlled = EnergyIntoHand(&pc, stroke, push, 5000, &lowest_controlled);
  EXPECT_LT(lowest_free, -0.009);
  EXPECT_GT(lowest_controlled, 0.05 * lowest_free);  // at least 20× less energy ever given
  EXPECT_LE(controlled, 1e-4);                       // and about none over the whole run
  EXPECT_GT(pc.dissipated(), 0.009);
}

TEST(PassivityTest, ASampledSpringLosesOnlyWhatTheHoldAdded) {
  // A real spring stores and returns energy; sampled and held it returns more than it took
  // (Σ k·Δx²/2: ~4 mJ over these 5 s, the equivalent of a negative damping k·Δt/2). The
  // controller removes that excess and no more, in corrections small beside the 2 N spring force.
  const auto stroke = [](int i) { return 0.01 * std::sin(2 * M_PI * 2 * i * kDt); };
  const auto spring = [](double x) { return -200 * x; };
  const double excess = EnergyIntoHand(nullptr, stroke, spring, 5000);
  PassivityController pc;
  double largest = 0;
  for (int i = 0; i <= 5000; ++i) {
    const double x = stroke(i);
    const Eigen::Vector3d f(spring(x), 0, 0);
    largest = std::max(largest, (pc.Apply(f, Eigen::Vector3d(x, 0, 0), kDt) - f).norm());
  }
  EXPECT_GT(excess, 3e-3);
  EXPECT_LT(pc.dissipated(), 1.05 * excess);
  EXPECT_GT(pc.energy(), -2e-4);
  EXPECT_LT(largest, 0.3);  // 15% of the spring's peak
}

TEST(PassivityTest, ATremorAgainstAStiffSampledSpringIsHeldToTheReserve) {
  // 700 N/m (an Omni-class device's limit) under an 8 Hz, 1 mm tremor for 4 s gives the hand
  // ~3 mJ uncontrolled; controlled, the balance never falls far below the reserve.
  const auto tremor = [](int i) { return 0.001 * std::sin(2 * M_PI * 8 * i * kDt); };
  const auto spring = [](double x) { return -700 * x; };
  const double free = EnergyIntoHand(nullptr, tremor, spring, 4000);
  PassivityController pc;
  double lowest = 0;
  const double controlled = EnergyIntoHand(&pc, tremor, spring, 4000, &lowest);
  EXPECT_GT(free, 1e-3);
  EXPECT_LT(controlled, 0.2 * free);
  EXPECT_GT(lowest, -2e-4);
}

TEST(PassivityTest, TheForceActuallyHeldIsWhatCounts) {
  // The safety filter may output less than was asked (a clamp, the start-up gate): the observer
  // must count the force the device held, not the request.
  PassivityController observer(0.0);
  observer.Apply(Eigen::Vector3d(5, 0, 0), Eigen::Vector3d::Zero(), kDt);
  observer.Held(Eigen::Vector3d::Zero());  // gated: nothing output
  observer.Apply(Eigen::Vector3d(5, 0, 0), Eigen::Vector3d(0.01, 0, 0), kDt);
  EXPECT_EQ(observer.energy(), 0);
  observer.Held(Eigen::Vector3d(1, 0, 0));
  observer.Apply(Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d(0.02, 0, 0), kDt);
  EXPECT_DOUBLE_EQ(observer.energy(), -0.01);  // 1 N over 1 cm, given to the hand
  EXPECT_DOUBLE_EQ(observer.to_hand(), 0.01);
}

TEST(PassivityTest, FreeSpaceStartsTheBalanceAfreshAndNeverDragsTheHand) {
  // A debt left by the last contact is not settled by damping a free hand (felt as drag): with
  // nothing requested, nothing is output and the balance restarts; the totals keep the record.
  PassivityController pc(50.0, 0.0);
  pc.Apply(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero(), kDt);
  pc.Apply(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.01, 0, 0), kDt);  // 10 mJ given
  EXPECT_NE(pc.Apply(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.02, 0, 0), kDt),
            Eigen::Vector3d(1, 0, 0));  // in contact, the controller acts
  EXPECT_EQ(pc.Apply(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.03, 0, 0), kDt),
            Eigen::Vector3d::Zero());
  EXPECT_EQ(pc.Apply(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.04, 0, 0), kDt),
            Eigen::Vector3d::Zero());
  EXPECT_EQ(pc.energy(), 0);
  EXPECT_DOUBLE_EQ(pc.to_hand(), 0.01);  // the damped third force was exactly what settled it
}

TEST(PassivityTest, AnEncoderCountFlickeringIsNotDampedIntoABuzz) {
  // A hand at rest on a 0.055 mm count boundary reads x flicking between two counts, while the
  // balance is in debt (a 1 N force gave the hand about 1 mJ first, part of it damped). Damped on
  // the last step's velocity (55 mm/s per count) at 5 N·s/m, each flick drew a 0.27 N kick whose
  // work against the next flick read as more debt: a 250 Hz buzz. On the mean velocity over 8
  // intervals the kicks stay under 0.04 N and the debt does not grow from the controller's own
  // work.
  PassivityController pc(5.0);
  const Eigen::Vector3d f(1, 0, 0);
  double x = 0;
  for (int i = 0; i < 10; ++i, x += 1e-4) pc.Apply(f, Eigen::Vector3d(x, 0, 0), kDt);  // 1 mJ
  ASSERT_LT(pc.energy(), -3e-4);
  const double count = 0.055e-3;
  const double debt = pc.energy();
  double largest = 0;
  for (int i = 0; i < 400; ++i) {
    const double flick = ((i / 2) % 2 == 0) ? 0.0 : count;  // 4-cycle pattern, as the hand gave
    const Eigen::Vector3d out = pc.Apply(f, Eigen::Vector3d(x + flick, 0, 0), kDt);
    if (i >= PassivityController::kVelocityWindow)  // the approach has left the window
      largest = std::max(largest, (out - f).norm());
  }
  EXPECT_LT(largest, 0.04);
  EXPECT_GT(pc.energy(), debt - 1e-4);
}

TEST(PassivityTest, ATwistFieldsDeclaredEnergyIsAllowed) {
  // A field that grows with the stylus's turn pushes a yielding hand: 0.9 N over 0.6 mm is
  // 0.54 mJ given, by the grasp's design. Declared (|F|²/2k = 2 mJ at a 200 N/m hold), the
  // controller leaves the force alone; undeclared, it damps it.
  for (const double allowance : {0.0, 2e-3}) {
    PassivityController pc(5.0);
    double changed = 0, x = 0;
    for (int i = 0; i <= 600; ++i, x += 1e-6) {
      const Eigen::Vector3d f(0.9 * std::min(1.0, i / 300.0), 0, 0);
      changed =
          std::max(changed, (pc.Apply(f, Eigen::Vector3d(x, 0, 0), kDt, allowance) - f).norm());
    }
    if (allowance > 0) {
      EXPECT_EQ(changed, 0) << allowance;
    } else {
      EXPECT_GT(changed, 0) << allowance;
    }
    EXPECT_LT(pc.energy(), -4e-4);
  }
}

// A hand presses 2 mm into a 300 N/m surface and lets it push the tool back out. The station
// sends every sample; the server receives sample i at cycle i + delay/2, its spring answering
// there (its port flows through sample i), and that answer reaches the station delay/2 later.
// The server's spring keeps `tissue_keeps` of what it would give back (a plastic dent: 1).
// Returns the lowest network balance, the largest pull into the surface and what the hand got.
struct PressResult {
  double lowest_balance = 0, largest_pull = 0, to_hand = 0;
};
double PressDepth(int i) {  // in over 400 ms, held 200 ms, out over 400 ms, then free
  return i < 400 ? 0.002 * i / 400 : i < 600 ? 0.002 : std::max(0.0, 0.002 * (1000 - i) / 400.0);
}
PressResult PressAndRelease(PassivityController& pc, int delay, double tissue_keeps = 0) {
  PressResult r;
  const int half = delay / 2;
  std::vector<std::pair<double, double>> report;  // the server's flows through sample i
  double released = 0, absorbed = 0, server_x = 0, server_f = 0;
  for (int i = 0; i <= 1400; ++i) {
    // The server: sample j = i − half arrives; its held force against the motion to it.
    if (const int j = i - half; j >= 0) {
      const double sx = -PressDepth(j);
      const double w = server_f * (sx - server_x);
      if (w > 0) released += w * (1 - tissue_keeps);
      if (w < 0) absorbed -= w;
      server_x = sx;
      server_f = 300 * PressDepth(j);
      report.emplace_back(released, absorbed);  // report[j]
    }
    // The station: the answer to sample i − delay (at least the previous one), if any, is here.
    if (const int e = i - std::max(1, 2 * half); e >= 0)
      pc.TissueReport(static_cast<uint64_t>(e), report[e].first, report[e].second);
    const double depth = PressDepth(i);
    const Eigen::Vector3d asked(depth > 0 ? 300 * depth : 0, 0, 0);
    const Eigen::Vector3d out = pc.Apply(asked, Eigen::Vector3d(-depth, 0, 0), kDt);
    pc.Sent(static_cast<uint64_t>(i));
    if (asked.x() > 0) r.largest_pull = std::max(r.largest_pull, -out.x());
    r.lowest_balance = std::min(r.lowest_balance, pc.network_balance());
  }
  r.to_hand = pc.to_hand();
  return r;
}

TEST(PassivityTest, TheNetworkControlGivesBackAheadOfTheRecordOnlyWhatTheHandJustPutIn) {
  // 300 ms round trip: the local spring pushes back the moment the hand lets it, the tissue's
  // record of its release arrives 300 ms later. The one-port sees a passive spring and lets it
  // return all 0.6 mJ ahead of the record; the two-port returns ahead of it only what the hand put
  // in within the last round trip (still on its way to the tissue), about a third here, and never
  // turns the push into a pull.
  PassivityController local(5.0, 1e-4, PassivityMode::kLocal);
  PassivityController network(5.0, 1e-4, PassivityMode::kNetwork);
  const PressResult l = PressAndRelease(local, 300);
  const PressResult n = PressAndRelease(network, 300);
  std::printf("lowest balance: one-port %.3f mJ, two-port %.3f mJ\n", l.lowest_balance * 1e3,
              n.lowest_balance * 1e3);
  EXPECT_LT(l.lowest_balance, -3e-4);
  EXPECT_GT(n.lowest_balance, 0.5 * l.lowest_balance);
  EXPECT_EQ(n.largest_pull, 0);
  EXPECT_GT(network.dissipated(), 2e-4);
  // With no delay the record keeps up and the network control hardly acts.
  PassivityController prompt(5.0, 1e-4, PassivityMode::kNetwork);
  const PressResult p = PressAndRelease(prompt, 0);
  EXPECT_LT(prompt.dissipated(), 0.05 * p.to_hand);
  EXPECT_GT(p.to_hand, 5e-4);  // the spring's ~0.6 mJ came back
}

TEST(PassivityTest, TheNetworkControlHoldsBackWhatATissueThatKeepsItsEnergyNeverReleases) {
  // A tissue that keeps what it was given (a plastic dent) releases nothing; a local model that
  // springs back would give the hand energy the tissue never had. The one-port cannot tell.
  PassivityController local(5.0, 1e-4, PassivityMode::kLocal);
  PassivityController network(5.0, 1e-4, PassivityMode::kNetwork);
  PressAndRelease(local, 20, 1.0);
  PressAndRelease(network, 20, 1.0);
  EXPECT_GT(local.to_hand(), 4e-4);
  EXPECT_LT(network.to_hand(), 1e-4 + 5e-5);
}

TEST(PassivityTest, ASessionReplacedOnAnotherServerKeepsTheAccount) {
  PassivityController pc(5.0, 1e-4, PassivityMode::kNetwork);
  for (uint64_t s = 1; s <= 5; ++s) pc.Sent(s);
  pc.TissueReport(1, 5e-3, 8e-3);
  pc.TissueReport(2, 6e-3, 9e-3);
  pc.TissueReport(3, 1e-3, 2e-3);  // a new server's counts start again
  EXPECT_DOUBLE_EQ(pc.released(), 7e-3);
  EXPECT_DOUBLE_EQ(pc.absorbed(), 11e-3);
  EXPECT_DOUBLE_EQ(pc.network_balance(), -4e-3);
  pc.TissueReport(4, NAN, 1);
  pc.TissueReport(4, 1, -1);
  pc.TissueReport(99, 1, 1);  // a sample never sent
  EXPECT_DOUBLE_EQ(pc.released(), 7e-3);
  EXPECT_DOUBLE_EQ(pc.absorbed(), 11e-3);
}

TEST(PassivityTest, NonFiniteInputGivesNoForce) {
  PassivityController pc;
  EXPECT_EQ(pc.Apply(Eigen::Vector3d(NAN, 0, 0), Eigen::Vector3d::Zero(), kDt),
            Eigen::Vector3d::Zero());
  EXPECT_EQ(pc.Apply(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(INFINITY, 0, 0), kDt),
            Eigen::Vector3d(1, 0, 0));
  EXPECT_TRUE(std::isfinite(pc.energy()));
}

}  // namespace
}  // namespace vsurg::client
