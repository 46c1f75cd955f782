// The proto mapping of a live session's sample (proto/convert), and the one mapping of a sample
// to named numbers with units (common/sim/telemetry.h).
#include "proto/convert/services.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace vsurg {
namespace {

sim::SessionTelemetry Sample() {
  sim::SessionTelemetry t;
  t.id = 42;
  t.state = SessionState::kRunning;
  t.server_time_us = 1'700'000'000'000'000;
  t.sim.time = 12.5;
  t.sim.force = {0.3, -1.2, 0.4};
  t.sim.tip = {0.01, 0.02, -0.03};
  t.sim.twist = M_PI / 4;
  t.sim.torque = 0.0123;
  t.sim.depth = 0.0075;
  t.sim.contact = true;
  t.sim.grasping = false;
  t.sim.samples = 12'345;
  t.sim.clock_jumps = 2;
  t.sim.guide_mode = 2;
  t.sim.guide_alpha = 0.375;
  t.sim.instructor = true;
  t.sim.instructor_tip = {0.011, 0.018, -0.025};
  t.sim.hands_apart = 0.0045;
  t.sim.metrics.score = 7.5;
  t.sim.metrics.overload_events = 3;
  t.sim.metrics.peak_force = 2.25;
  t.rtt_us = 412;
  t.packet_loss = 0.0125;
  t.packets = 12'000;
  t.haptic_rate_hz = 998;
  t.scene = "kidney-palpation";
  t.trainee = "ana";
  t.has_surface = true;
  t.surface_frame = 9;
  t.surface_indices = {1, 5};
  t.surface_positions = {{0.5, 0.25, 0.125}, {-1, 2, 3}};  // exact as floats
  return t;
}

TEST(ConvertTest, ASessionSampleSurvivesTheWireFieldForField) {
  const sim::SessionTelemetry t = Sample();
  v1::Telemetry wire;
  convert::ToProto(t, &wire);
  const sim::SessionTelemetry back = convert::FromProto(wire);
  EXPECT_EQ(back.id, t.id);
  EXPECT_EQ(back.state, t.state);
  EXPECT_EQ(back.server_time_us, t.server_time_us);
  EXPECT_EQ(back.sim.time, t.sim.time);
  EXPECT_EQ(back.sim.force, t.sim.force);
  EXPECT_EQ(back.sim.tip, t.sim.tip);
  EXPECT_EQ(back.sim.twist, t.sim.twist);
  EXPECT_EQ(back.sim.torque, t.sim.torque);
  EXPECT_EQ(back.sim.depth, t.sim.depth) << "a press scene's depth reaches a site's dashboard";
  EXPECT_EQ(back.sim.contact, t.sim.contact);
  EXPECT_EQ(back.sim.grasping, t.sim.grasping);
  EXPECT_EQ(back.sim.samples, t.sim.samples);
  EXPECT_EQ(back.sim.clock_jumps, t.sim.clock_jumps);
  EXPECT_EQ(back.sim.guide_mode, t.sim.guide_mode);
  EXPECT_EQ(back.sim.guide_alpha, t.sim.guide_alpha);
  EXPECT_EQ(back.sim.instructor, t.sim.instructor);
  EXPECT_EQ(back.sim.instructor_tip, t.sim.instructor_tip);
  EXPECT_EQ(back.sim.hands_apart, t.sim.hands_apart);
  EXPECT_EQ(back.sim.metrics.score, t.sim.metrics.score);
  EXPECT_EQ(back.sim.metrics.overload_events, t.sim.metrics.overload_events);
  EXPECT_EQ(back.rtt_us, t.rtt_us);
  EXPECT_EQ(back.packet_loss, t.packet_loss);
  EXPECT_EQ(back.packets, t.packets);
  EXPECT_EQ(back.haptic_rate_hz, t.haptic_rate_hz);
  EXPECT_EQ(back.scene, t.scene);
  EXPECT_EQ(back.trainee, t.trainee);
  ASSERT_TRUE(back.has_surface);
  EXPECT_EQ(back.surface_frame, t.surface_frame);
  EXPECT_EQ(back.surface_indices, t.surface_indices);
  EXPECT_EQ(back.surface_positions, t.surface_positions);
  // A message without a surface gives none.
  wire.clear_surface();
  EXPECT_FALSE(convert::FromProto(wire).has_surface);
}

TEST(ConvertTest, EveryFieldIsNamedWithItsUnitAndConvertedToIt) {
  const sim::SessionTelemetry t = Sample();
  const auto fields = sim::TelemetryFields(t);
  auto value = [&](std::string_view name) {
    for (const auto& f : fields)
      if (f.name == name) return f.value;
    ADD_FAILURE() << "no field " << name;
    return std::nan("");
  };
  EXPECT_DOUBLE_EQ(value("time_s"), 12.5);
  EXPECT_DOUBLE_EQ(value("force_n"), std::sqrt(0.09 + 1.44 + 0.16));
  EXPECT_DOUBLE_EQ(value("twist_deg"), 45.0);
  EXPECT_DOUBLE_EQ(value("torque_nm"), 0.0123);
  EXPECT_DOUBLE_EQ(value("depth_mm"), 7.5);
  EXPECT_DOUBLE_EQ(value("loss_ratio"), 0.0125);
  EXPECT_DOUBLE_EQ(value("rtt_us"), 412);
  EXPECT_DOUBLE_EQ(value("haptic_rate_hz"), 998);
  EXPECT_DOUBLE_EQ(value("peak_force_n"), 2.25);
  EXPECT_EQ(value("contact"), 1.0);
  EXPECT_EQ(value("grasping"), 0.0);
  EXPECT_EQ(value("samples"), 12'345);
  EXPECT_DOUBLE_EQ(value("tip_z_mm"), -30.0);
  EXPECT_DOUBLE_EQ(value("instructor_y_mm"), 18.0);
  EXPECT_DOUBLE_EQ(value("dominance_ratio"), 0.375);
  EXPECT_EQ(value("instructor"), 1.0);
  // Names are unique, and a real quantity's name ends in its unit.
  for (size_t i = 0; i < fields.size(); ++i) {
    for (size_t k = i + 1; k < fields.size(); ++k) EXPECT_NE(fields[i].name, fields[k].name);
    if (fields[i].kind == sim::TelemetryField::Kind::kReal && fields[i].name != "score") {
      const std::string_view n = fields[i].name;
      const bool unit = n.ends_with("_s") || n.ends_with("_n") || n.ends_with("_deg") ||
                        n.ends_with("_nm") || n.ends_with("_mm") || n.ends_with("_us") ||
                        n.ends_with("_ratio") || n.ends_with("_hz");
      EXPECT_TRUE(unit) << n;
    }
  }
  // The monitor's line is the same fields.
  const std::string line = sim::TelemetryText(t);
  EXPECT_NE(line.find("twist_deg=45.0"), std::string::npos) << line;
  EXPECT_NE(line.find("loss_ratio=0.0125"), std::string::npos) << line;
  EXPECT_NE(line.find("contact=1 grasping=0"), std::string::npos) << line;
  EXPECT_EQ(sim::LinkStatus(998, 412, 0.0125), "haptic 998 Hz   RTT 412 µs   loss 1.2%");
}

// A station's surface from its join, the tissue's static curve and its corners' yield with it;
// a curve whose yields and forces do not pair, or that falls, is refused by name.
TEST(ConvertTest, AStationSurfaceCarriesTheTissuesCurve) {
  haptics::SurfaceSpec spec;
  spec.positions = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}};
  spec.triangles = {{0, 1, 2}};
  spec.stiffness = {300, 300, 300};
  spec.tissue_stiffness = 132.9, spec.tissue_damping = 13;
  spec.tissue_curve.count = 3;
  spec.tissue_curve.yield = {0.2e-3, 1e-3, 5e-3};
  spec.tissue_curve.force = {0.088, 0.288, 0.897};
  spec.corners_yield = true;
  auto surface = haptics::TissueSurface::Create(spec);
  ASSERT_TRUE(surface.ok());
  v1::StationSurface wire;
  convert::ToProto(**surface, &wire);
  auto back = convert::FromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  const haptics::SurfaceSpec& b = (*back)->spec();
  EXPECT_EQ(b.tissue_curve.count, 3);
  EXPECT_EQ(b.tissue_curve.yield, spec.tissue_curve.yield);
  EXPECT_EQ(b.tissue_curve.force, spec.tissue_curve.force);
  EXPECT_TRUE(b.corners_yield);
  EXPECT_EQ(b.tissue_stiffness, 132.9);
  v1::StationSurface odd = wire;
  odd.add_tissue_curve_yield(6e-3);
  EXPECT_EQ(convert::FromProto(odd).error().field, "surface");
  v1::StationSurface falling = wire;
  falling.set_tissue_curve_force(2, 0.1);
  EXPECT_EQ(convert::FromProto(falling).error().field, "surface");
  v1::StationSurface many = wire;
  for (int i = 0; i < 20; ++i) many.add_tissue_curve_yield(1), many.add_tissue_curve_force(1);
  EXPECT_EQ(convert::FromProto(many).error().field, "surface");
}

}  // namespace
}  // namespace vsurg
