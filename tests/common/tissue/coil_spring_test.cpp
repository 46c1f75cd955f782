#include "common/tissue/coil_spring.h"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace vsurg::tissue {
namespace {

constexpr double kPi = std::numbers::pi;

// A hand-workable model: r = h = b = 1, E = 12 (so E·I = 1), κ = 1, S = 3, F_t = 1/(2π), which
// makes C_i = R_i: capacities 2, 3, 4 and cumulative 2, 5, 9; φ_i = M_i·2π·R_i.
CoilSpringParams HandParams() {
  CoilSpringParams p;
  p.core_radius = 1;
  p.thickness = 1;
  p.width = 1;
  p.coils = 3;
  p.modulus = 12;
  p.max_force = 1 / (2 * kPi);
  p.friction = 1;
  return p;
}

CoilSpringModel Make(const CoilSpringParams& p) {
  auto m = CoilSpringModel::Create(p);
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  return *m;
}

TEST(CoilSpringTest, ForwardMatchesHandWorkedValues) {
  const CoilSpringModel m = Make(HandParams());
  EXPECT_DOUBLE_EQ(m.Capacity(), 9);
  const CoilState st = m.Forward(4.0);
  // Q_1 = 2 < 4 ≤ Q_2 = 5: P = 2, M_1 = C_1 = 2 (eq. 3), M_2 = 4 − 2 = 2 (eq. 4).
  ASSERT_EQ(st.cutoff, 2);
  EXPECT_FALSE(st.overload);
  EXPECT_NEAR(st.coil_torques[0], 2, 1e-12);
  EXPECT_NEAR(st.coil_torques[1], 2, 1e-12);
  // n_i = κ·M_i·l_i/(2π·E·I) = M_i·R_i (eq. 6): 4 and 6 turns; φ_i = 8π and 12π.
  EXPECT_NEAR(st.twist_turns[0], 4, 1e-12);
  EXPECT_NEAR(st.twist_turns[1], 6, 1e-12);
  EXPECT_NEAR(st.twist_angles[0], 8 * kPi, 1e-12);
  EXPECT_NEAR(st.twist_angles[1], 12 * kPi, 1e-12);
  EXPECT_NEAR(st.total_twist, 20 * kPi, 1e-12);
  EXPECT_NEAR(st.boundary_angles[0], 20 * kPi, 1e-12);
  EXPECT_NEAR(st.boundary_angles[1], 12 * kPi, 1e-12);
  EXPECT_EQ(st.boundary_angles[2], 0.0);
  // Twist profile: Φ in the core, linear inside ring 2 (R_1 = 2 .. R_2 = 3), zero from R_P on.
  EXPECT_NEAR(m.TwistAt(0.5, st), 20 * kPi, 1e-12);
  EXPECT_NEAR(m.TwistAt(1.5, st), 16 * kPi, 1e-12);
  EXPECT_NEAR(m.TwistAt(2.5, st), 6 * kPi, 1e-12);
  EXPECT_EQ(m.TwistAt(3.0, st), 0.0);
  EXPECT_EQ(m.TwistAt(10.0, st), 0.0);
}

TEST(CoilSpringTest, PointForceOfTheCutoffCoilIsBelowTheMaximum) {
  // eq. 5: F_P = M_P/(2π·R_P) ≤ F_t, with equality only when the coil is full.
  const CoilSpringModel m = Make(HandParams());
  for (double torque : {0.5, 2.0, 3.5, 5.0, 8.9}) {
    const CoilState st = m.Forward(torque);
    const double f_p = st.coil_torques[st.cutoff - 1] / (2 * kPi * m.RingRadius(st.cutoff));
    EXPECT_GT(f_p, 0);
    EXPECT_LE(f_p, m.params().max_force * (1 + 1e-12));
  }
}

TEST(CoilSpringTest, CutoffLayerIsTheFirstCoilWhoseCumulativeCapacityReachesTheTorque) {
  const CoilSpringModel m = Make(HandParams());
  const double q1 = m.CoilCapacity(1), q2 = q1 + m.CoilCapacity(2);
  EXPECT_NEAR(q1, 2.0, 1e-15);
  EXPECT_EQ(m.Forward(0.0).cutoff, 0);
  EXPECT_EQ(m.Forward(1e-9).cutoff, 1);
  EXPECT_EQ(m.Forward(q1).cutoff, 1);  // exactly full: still P = 1
  EXPECT_EQ(m.Forward(q1 + 1e-9).cutoff, 2);
  EXPECT_EQ(m.Forward(q2).cutoff, 2);
  EXPECT_EQ(m.Forward(m.Capacity()).cutoff, 3);
  EXPECT_FALSE(m.Forward(m.Capacity()).overload);
}

TEST(CoilSpringTest, OverloadClampsToCapacityAndIsReported) {
  const CoilSpringModel m = Make(HandParams());
  const CoilState at = m.Forward(m.Capacity());
  const CoilState over = m.Forward(100.0);
  EXPECT_TRUE(over.overload);
  EXPECT_EQ(over.cutoff, 3);
  EXPECT_EQ(over.torque, m.Capacity());
  EXPECT_EQ(over.requested_torque, 100.0);
  EXPECT_DOUBLE_EQ(over.total_twist, at.total_twist);  // never extrapolated
  EXPECT_NEAR(over.total_twist, 58 * kPi, 1e-12);      // 8π + 18π + 32π
  const CoilState under = m.Forward(-100.0);
  EXPECT_TRUE(under.overload);
  EXPECT_EQ(under.torque, -m.Capacity());
}

TEST(CoilSpringTest, NegativeTorqueMirrors) {
  const CoilSpringModel m = Make(HandParams());
  const CoilState pos = m.Forward(6.5), neg = m.Forward(-6.5);
  ASSERT_EQ(pos.cutoff, neg.cutoff);
  for (int i = 0; i < pos.cutoff; ++i) {
    EXPECT_EQ(neg.coil_torques[i], -pos.coil_torques[i]);
    EXPECT_EQ(neg.twist_angles[i], -pos.twist_angles[i]);
  }
  EXPECT_EQ(neg.total_twist, -pos.total_twist);
  EXPECT_EQ(m.TwistAt(2.5, neg), -m.TwistAt(2.5, pos));
}

TEST(CoilSpringTest, NonFiniteTorqueGivesZeroAndAFlag) {
  const CoilSpringModel m = Make(HandParams());
  for (double bad : {NAN, INFINITY, -INFINITY}) {
    const CoilState st = m.Forward(bad);
    EXPECT_TRUE(st.invalid_input);
    EXPECT_EQ(st.total_twist, 0.0);
    EXPECT_EQ(st.cutoff, 0);
    const CoilTorque t = m.Inverse(bad);
    EXPECT_TRUE(t.invalid_input);
    EXPECT_EQ(t.torque, 0.0);
  }
}

TEST(CoilSpringTest, InverseMatchesHandWorkedValues) {
  const CoilSpringModel m = Make(HandParams());
  const CoilTorque t = m.Inverse(20 * kPi);
  EXPECT_NEAR(t.torque, 4.0, 1e-12);
  EXPECT_EQ(t.cutoff, 2);
  // Segment 2 slope dΦ/dM = κ·2π·R_2/(E·I) = 6π.
  EXPECT_NEAR(t.stiffness, 1 / (6 * kPi), 1e-15);
  const CoilTorque past = m.Inverse(60 * kPi);
  EXPECT_TRUE(past.overload);
  EXPECT_EQ(past.torque, m.Capacity());
  EXPECT_EQ(past.stiffness, 0.0);
  const CoilTorque zero = m.Inverse(0.0);
  EXPECT_EQ(zero.torque, 0.0);
  EXPECT_NEAR(zero.stiffness, 1 / (4 * kPi), 1e-15);  // first segment
}

// Φ(M) continuous and increasing across every breakpoint; slope as DESIGN.md states.
TEST(CoilSpringTest, TwistIsContinuousIncreasingAndPiecewiseLinear) {
  const CoilSpringModel m = Make(HandParams());
  double cum = 0;
  for (int p = 1; p <= 3; ++p) {
    cum += m.CoilCapacity(p);
    const double eps = 1e-7;
    const double below = m.Forward(cum - eps).total_twist, at = m.Forward(cum).total_twist,
                 above = m.Forward(cum + eps).total_twist;
    EXPECT_LT(below, at);
    EXPECT_NEAR(at - below, eps * m.SegmentCompliance(p), 1e-9);  // no jump at the breakpoint
    if (p < 3) {
      EXPECT_NEAR(above - at, eps * m.SegmentCompliance(p + 1), 1e-9);
    }
  }
  double prev = -1;
  for (int k = 0; k <= 900; ++k) {
    const double tw = m.Forward(0.01 * k).total_twist;
    EXPECT_GT(tw, prev);
    prev = tw;
  }
}

TEST(CoilSpringTest, InverseUndoesForwardAcrossSegmentsAndSigns) {
  const CoilSpringModel m = Make(HandParams());
  for (double torque = -8.95; torque <= 8.95; torque += 0.05) {
    const CoilState st = m.Forward(torque);
    const CoilTorque back = m.Inverse(st.total_twist);
    EXPECT_NEAR(back.torque, torque, 1e-12 * 9) << torque;
    EXPECT_EQ(back.cutoff, st.cutoff) << torque;
    EXPECT_FALSE(back.overload);
  }
}

TEST(CoilSpringTest, ParametersAreValidatedWithTheFieldNamed) {
  struct Case {
    const char* field;
    void (*mutate)(CoilSpringParams&);
  };
  const Case cases[] = {
      {"core_radius", [](CoilSpringParams& p) { p.core_radius = 0; }},
      {"core_radius", [](CoilSpringParams& p) { p.core_radius = NAN; }},
      {"thickness", [](CoilSpringParams& p) { p.thickness = -0.01; }},
      {"width", [](CoilSpringParams& p) { p.width = 0; }},
      {"modulus", [](CoilSpringParams& p) { p.modulus = -1; }},
      {"modulus", [](CoilSpringParams& p) { p.modulus = INFINITY; }},
      {"max_force", [](CoilSpringParams& p) { p.max_force = 0; }},
      {"friction", [](CoilSpringParams& p) { p.friction = 0; }},
      {"coils", [](CoilSpringParams& p) { p.coils = 0; }},
      {"coils", [](CoilSpringParams& p) { p.coils = -3; }},
      {"coils", [](CoilSpringParams& p) { p.coils = CoilSpringModel::kMaxCoils + 1; }},
      {"coil_rigidity",
       [](CoilSpringParams& p) {
         p.coil_rigidity = {1.0, 2.0};
       }},
      {"coil_rigidity",
       [](CoilSpringParams& p) {
         p.coil_rigidity = {1.0, 0.0, 1.0};
       }},
      {"modulus",
       [](CoilSpringParams& p) {
         p.modulus = 1e-320;
         p.width = 1e-10;
       }},
  };
  for (const Case& c : cases) {
    CoilSpringParams p = HandParams();
    c.mutate(p);
    auto m = CoilSpringModel::Create(p);
    ASSERT_FALSE(m.ok()) << c.field;
    EXPECT_EQ(m.error().field, c.field);
    EXPECT_EQ(m.error().code, ErrorCode::kInvalidArgument);
    EXPECT_FALSE(m.error().message.empty());
  }
}

TEST(CoilSpringTest, PerCoilRigidityChangesOnlyThatCoilsTwist) {
  CoilSpringParams p = HandParams();
  p.coil_rigidity = {1.0, 2.0, 1.0};
  const CoilSpringModel m = Make(p), base = Make(HandParams());
  const CoilState a = m.Forward(4.0), b = base.Forward(4.0);
  EXPECT_DOUBLE_EQ(a.twist_angles[0], b.twist_angles[0]);
  EXPECT_DOUBLE_EQ(a.twist_angles[1], 0.5 * b.twist_angles[1]);
  EXPECT_NEAR(m.Inverse(a.total_twist).torque, 4.0, 1e-12);
}

TEST(CoilSpringTest, ForwardIntoAPreparedStateDoesNotReallocate) {
  const CoilSpringModel m = Make(HandParams());
  CoilState st = m.MakeState();
  const double* data = st.boundary_angles.data();
  for (double t : {1.0, 7.0, 100.0, -3.0}) m.Forward(t, st);
  EXPECT_EQ(st.boundary_angles.data(), data);
}

// Property test over random valid parameters (fixed seed): invariants that must hold for any.
TEST(CoilSpringTest, RandomParametersKeepTheInvariants) {
  std::mt19937_64 rng(20261121);
  auto log_uniform = [&](double lo, double hi) {
    return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(rng));
  };
  for (int trial = 0; trial < 300; ++trial) {
    CoilSpringParams p;
    p.core_radius = log_uniform(1e-3, 0.1);
    p.thickness = log_uniform(1e-3, 0.05);
    p.width = log_uniform(1e-3, 0.2);
    p.coils = std::uniform_int_distribution<int>(1, 60)(rng);
    p.modulus = log_uniform(1e3, 1e10);
    p.max_force = log_uniform(1e-3, 10);
    p.friction = log_uniform(0.5, 2);
    const CoilSpringModel m = Make(p);
    const double cap = m.Capacity();
    const double torque = std::uniform_real_distribution<double>(-1.3 * cap, 1.3 * cap)(rng);
    const CoilState st = m.Forward(torque);
    SCOPED_TRACE(trial);
    ASSERT_TRUE(std::isfinite(st.total_twist));
    EXPECT_EQ(st.overload, std::abs(torque) > cap);
    // Coil torques sum to the applied torque; each within its capacity.
    double sum = 0, turns = 0;
    for (int i = 0; i < st.cutoff; ++i) {
      sum += st.coil_torques[i];
      turns += st.twist_turns[i];
      EXPECT_LE(std::abs(st.coil_torques[i]), m.CoilCapacity(i + 1) * (1 + 1e-12));
      EXPECT_NEAR(st.twist_angles[i], 2 * kPi * st.twist_turns[i],
                  1e-12 * std::abs(st.twist_angles[i]));
    }
    EXPECT_NEAR(sum, st.torque, 1e-10 * cap);
    EXPECT_NEAR(2 * kPi * turns, st.total_twist, 1e-10 * std::abs(st.total_twist));
    // Boundary angles decrease in magnitude outward, from Φ to 0.
    for (int k = 0; k < st.cutoff; ++k) {
      EXPECT_GE(std::abs(st.boundary_angles[k]), std::abs(st.boundary_angles[k + 1]));
    }
    // Inverse∘forward is the identity below capacity.
    if (!st.overload) {
      const CoilTorque back = m.Inverse(st.total_twist);
      EXPECT_NEAR(back.torque, torque, 1e-9 * cap);
      EXPECT_GT(back.stiffness, 0);
    }
    // |θ(ρ)| is non-increasing in ρ.
    double prev = std::abs(m.TwistAt(0, st));
    for (int k = 1; k <= 50; ++k) {
      const double tw = std::abs(m.TwistAt(m.RingRadius(p.coils) * k / 50.0, st));
      EXPECT_LE(tw, prev * (1 + 1e-12) + 1e-300);
      prev = tw;
    }
  }
}

}  // namespace
}  // namespace vsurg::tissue
