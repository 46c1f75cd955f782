#include "common/haptics/stiffness_fit.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace vsurg::haptics {
namespace {

constexpr double kDt = 1e-3;  // s, one servo cycle

// A press into a spring of stiffness k behind an offset, at 1 kHz, with the device's encoder
// noise on the depth (±0.03 mm) and force noise (±5 mN): the fit recovers k.
TEST(StiffnessFitTest, APressIntoALinearSpringGivesItsSlope) {
  for (const double k : {120.0, 300.0, 700.0}) {
    StiffnessFit fit;
    fit.BeginContact();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> noise(-1, 1);
    for (int i = 0; i < 400; ++i) {  // 0.4 s down to 4 mm
      const double depth = 1e-5 * i;
      fit.Add(depth + 3e-5 * noise(rng), 0.05 + k * depth + 5e-3 * noise(rng), kDt);
    }
    EXPECT_NEAR(fit.Stiffness(0, 1e4, -1), k, 0.03 * k) << k;
  }
}

// A tool resting in the tissue, or trembling within a tenth of a millimetre, says nothing about
// the slope: the prior stands before any fit, and the last fit (the same tissue) after one.
TEST(StiffnessFitTest, ATrembleOrARestKeepsWhatWasKnown) {
  StiffnessFit fit;
  fit.BeginContact();
  for (int i = 0; i < 2000; ++i) {
    const double depth = 2e-3 + 1e-4 * std::sin(2 * M_PI * 8 * i * kDt);  // 8 Hz, ±0.1 mm
    fit.Add(depth, 200 * depth, kDt);
  }
  EXPECT_EQ(fit.Stiffness(10, 700, 700), 700) << "a tremble was taken for a press";
  fit.BeginContact();
  for (int i = 0; i < 300; ++i) fit.Add(1e-5 * i, 200 * 1e-5 * i, kDt);  // a press at 200 N/m
  EXPECT_NEAR(fit.Stiffness(10, 700, 700), 200, 2);
  fit.BeginContact();  // a new contact on the same tissue, resting
  for (int i = 0; i < 500; ++i) fit.Add(1e-3, 0.2, kDt);
  EXPECT_NEAR(fit.Stiffness(10, 700, 700), 200, 2);
}

// The fit follows a tissue that stiffens (geometric nonlinearity): it gives the slope of the
// last few time constants (between k 3τ of pressing ago and k now), and the caller's bounds hold
// whatever the samples say.
TEST(StiffnessFitTest, ItFollowsAStiffeningTissueWithinItsBounds) {
  StiffnessFit fit;
  fit.BeginContact();
  double f = 0;
  for (int i = 0; i < 1000; ++i) {  // 1 s down to 5 mm: k(d) = 100 + 4·10⁴·d N/m
    const double d = 5e-6 * i;
    f += (100 + 4e4 * d) * 5e-6;
    fit.Add(d, f, kDt);
  }
  const double k_end = 100 + 4e4 * 5e-3;                                              // 300 N/m
  const double k_lag = 100 + 4e4 * (5e-3 - 3 * StiffnessFit::kTimeConstantS * 5e-3);  // 210 N/m
  EXPECT_GT(fit.Stiffness(0, 1e4, -1), k_lag) << "the fit lags the tissue";
  EXPECT_LT(fit.Stiffness(0, 1e4, -1), k_end);
  EXPECT_EQ(fit.Stiffness(0, 150, -1), 150);
  EXPECT_EQ(fit.Stiffness(400, 1e4, -1), 400);
}

// A falling slope (letting up faster than the tissue recovers) and non-finite samples never
// make the rendered stiffness negative, infinite or NaN.
TEST(StiffnessFitTest, NegativeAndNonFiniteSamplesNeverReachTheSlope) {
  StiffnessFit fit;
  fit.BeginContact();
  for (int i = 0; i < 300; ++i) fit.Add(1e-5 * i, 0.5 - 300 * 1e-5 * i, kDt);  // f falls with d
  EXPECT_EQ(fit.Stiffness(30, 300, 300), 300) << "a negative slope was taken";
  fit.BeginContact();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 300; ++i) fit.Add(1e-5 * i, 250 * 1e-5 * i, kDt);
  const double before = fit.Stiffness(30, 300, 300);
  fit.Add(nan, 1, kDt);
  fit.Add(1, inf, kDt);
  fit.Add(1e-3, 0.1, nan);
  EXPECT_EQ(fit.Stiffness(30, 300, 300), before);
  EXPECT_NEAR(before, 250, 3);
}

}  // namespace
}  // namespace vsurg::haptics
