#include "proto/convert/services.h"

#include <cmath>

namespace vsurg::convert {

v1::SessionState ToProto(SessionState s) {
  return static_cast<v1::SessionState>(static_cast<int>(s));
}

std::optional<SessionState> FromProto(v1::SessionState s) {
  return SessionStateFromNumber(static_cast<int>(s));
}

std::string StateName(v1::SessionState s) {
  const auto state = FromProto(s);
  return state ? SessionStateName(*state) : "unspecified";
}

void ToProto(const scoring::TrialMetrics& m, v1::TrialMetrics* out) {
  out->set_completed(m.completed);
  out->set_completion_time_s(m.completion_time);
  out->set_task_error(m.task_error);
  out->set_peak_force_n(m.peak_force);
  out->set_time_over_force_limit_s(m.time_over_force_limit);
  out->set_path_length_m(m.path_length);
  out->set_rms_jerk(m.rms_jerk);
  out->set_overload_events(m.overload_events);
  out->set_duration_s(m.duration);
  out->set_score(m.score);
  out->set_raw_score(m.raw_score);
  out->set_caps(m.caps);
  out->set_station_peak_force_n(m.link.station_peak_force);
  out->set_station_time_over_limit_s(m.link.station_time_over_limit);
  out->set_link_rtt_ms(m.link.rtt_ms);
  out->set_link_jitter_ms(m.link.jitter_ms);
  out->set_link_loss_ratio(m.link.loss);
  out->set_link_rate_hz(m.link.rate_hz);
  out->set_guided_share(m.guided_share);
  out->set_guided_alpha(m.guided_alpha);
  out->set_lumps(m.lumps);
  out->set_lumps_found(m.lumps_found);
  out->set_false_marks(m.false_marks);
  out->set_localisation_error_m(m.localisation_error);
  out->set_coverage(m.coverage);
  out->set_mean_force_n(m.mean_force);
  out->set_depth_error_m(m.depth_error);
  out->set_path_deviation_m(m.path_deviation);
  out->set_punctures(m.punctures);
  out->set_extra_punctures(m.extra_punctures);
  out->set_back_wall_breaches(m.back_wall_breaches);
  out->set_lateral_strain(m.lateral_strain);
  out->set_cut_deviation_max_m(m.cut_deviation_max);
  out->set_cut_outside_m(m.cut_outside);
  out->set_torn_length_m(m.torn_length);
  out->set_cut_lifts(m.cut_lifts);
}

void ToProto(const scoring::TaskSettings& t, v1::TaskSettings* out) {
  if (t.kind) out->set_kind(scoring::TaskKindName(*t.kind));
  if (t.target) out->set_target(*t.target);
  if (t.tolerance) out->set_tolerance(*t.tolerance);
  if (t.hold_s) out->set_hold_s(*t.hold_s);
  if (t.force_limit) out->set_force_limit_n(*t.force_limit);
  if (t.time_limit) out->set_time_limit_s(*t.time_limit);
}

scoring::TaskSettings FromProto(const v1::TaskSettings& t) {
  scoring::TaskSettings out;
  if (t.kind() == "twist") out.kind = scoring::TaskKind::kTwist;
  if (t.kind() == "press") out.kind = scoring::TaskKind::kPress;
  if (t.kind() == "palpate") out.kind = scoring::TaskKind::kPalpate;
  if (t.kind() == "insert") out.kind = scoring::TaskKind::kInsert;
  if (t.has_target()) out.target = t.target();
  if (t.has_tolerance()) out.tolerance = t.tolerance();
  if (t.has_hold_s()) out.hold_s = t.hold_s();
  if (t.has_force_limit_n()) out.force_limit = t.force_limit_n();
  if (t.has_time_limit_s()) out.time_limit = t.time_limit_s();
  return out;
}

scoring::TrialMetrics FromProto(const v1::TrialMetrics& m) {
  scoring::TrialMetrics out;
  out.completed = m.completed();
  out.completion_time = m.completion_time_s();
  out.task_error = m.task_error();
  out.peak_force = m.peak_force_n();
  out.time_over_force_limit = m.time_over_force_limit_s();
  out.path_length = m.path_length_m();
  out.rms_jerk = m.rms_jerk();
  out.overload_events = m.overload_events();
  out.duration = m.duration_s();
  out.score = m.score();
  out.raw_score = m.raw_score();
  out.caps = m.caps();
  out.link.station_peak_force = m.station_peak_force_n();
  out.link.station_time_over_limit = m.station_time_over_limit_s();
  out.link.rtt_ms = m.link_rtt_ms();
  out.link.jitter_ms = m.link_jitter_ms();
  out.link.loss = m.link_loss_ratio();
  out.link.rate_hz = m.link_rate_hz();
  out.guided_share = m.guided_share();
  out.guided_alpha = m.guided_alpha();
  out.lumps = m.lumps();
  out.lumps_found = m.lumps_found();
  out.false_marks = m.false_marks();
  out.localisation_error = m.localisation_error_m();
  out.coverage = m.coverage();
  out.mean_force = m.mean_force_n();
  out.depth_error = m.depth_error_m();
  out.path_deviation = m.path_deviation_m();
  out.punctures = m.punctures();
  out.extra_punctures = m.extra_punctures();
  out.back_wall_breaches = m.back_wall_breaches();
  out.lateral_strain = m.lateral_strain();
  out.cut_deviation_max = m.cut_deviation_max_m();
  out.cut_outside = m.cut_outside_m();
  out.torn_length = m.torn_length_m();
  out.cut_lifts = m.cut_lifts();
  return out;
}

void ToProto(const sim::SessionTelemetry& t, v1::Telemetry* out, bool with_surface) {
  out->set_session_id(t.id);
  out->set_server_time_us(t.server_time_us);
  out->set_state(ToProto(t.state));
  out->mutable_force()->set_x(t.sim.force.x());
  out->mutable_force()->set_y(t.sim.force.y());
  out->mutable_force()->set_z(t.sim.force.z());
  out->set_twist(t.sim.twist);
  out->set_torque(t.sim.torque);
  out->set_contact(t.sim.contact);
  out->set_grasping(t.sim.grasping);
  ToProto(t.sim.metrics, out->mutable_metrics());
  out->set_rtt_us(t.rtt_us);
  out->set_packet_loss(t.packet_loss);
  out->set_packets(t.packets);
  out->set_haptic_rate_hz(t.haptic_rate_hz);
  out->mutable_tip()->set_x(t.sim.tip.x());
  out->mutable_tip()->set_y(t.sim.tip.y());
  out->mutable_tip()->set_z(t.sim.tip.z());
  out->set_scene(t.scene);
  out->set_trainee(t.trainee);
  out->set_time_s(t.sim.time);
  out->set_depth(t.sim.depth);
  out->set_samples(t.sim.samples);
  out->set_clock_jumps(t.sim.clock_jumps);
  out->set_guide_mode(t.sim.guide_mode);
  out->set_guide_alpha(t.sim.guide_alpha);
  out->set_instructor(t.sim.instructor);
  out->mutable_instructor_tip()->set_x(t.sim.instructor_tip.x());
  out->mutable_instructor_tip()->set_y(t.sim.instructor_tip.y());
  out->mutable_instructor_tip()->set_z(t.sim.instructor_tip.z());
  out->set_hands_apart(t.sim.hands_apart);
  if (with_surface && t.has_surface) {
    v1::SurfaceState* surface = out->mutable_surface();
    surface->set_frame_id(t.surface_frame);
    surface->mutable_indices()->Assign(t.surface_indices.begin(), t.surface_indices.end());
    auto* p = surface->mutable_positions();
    p->Reserve(static_cast<int>(3 * t.surface_positions.size()));
    for (const geometry::Vec3& v : t.surface_positions)
      for (int k = 0; k < 3; ++k) p->Add(static_cast<float>(v[k]));
  }
}

sim::SessionTelemetry FromProto(const v1::Telemetry& t) {
  sim::SessionTelemetry s;
  s.id = t.session_id();
  s.state = FromProto(t.state()).value_or(SessionState::kAborted);
  s.server_time_us = t.server_time_us();
  s.sim.force = {t.force().x(), t.force().y(), t.force().z()};
  s.sim.tip = {t.tip().x(), t.tip().y(), t.tip().z()};
  s.sim.guide_mode = t.guide_mode() <= 2 ? t.guide_mode() : 0;
  s.sim.guide_alpha = t.guide_alpha();
  s.sim.instructor = t.instructor();
  s.sim.instructor_tip = {t.instructor_tip().x(), t.instructor_tip().y(), t.instructor_tip().z()};
  s.sim.hands_apart = t.hands_apart();
  s.sim.twist = t.twist();
  s.sim.torque = t.torque();
  s.sim.contact = t.contact();
  s.sim.grasping = t.grasping();
  s.sim.metrics = FromProto(t.metrics());
  s.rtt_us = t.rtt_us();
  s.packet_loss = t.packet_loss();
  s.packets = t.packets();
  s.haptic_rate_hz = t.haptic_rate_hz();
  s.scene = t.scene();
  s.trainee = t.trainee();
  s.sim.time = t.time_s();
  s.sim.depth = t.depth();
  s.sim.samples = t.samples();
  s.sim.clock_jumps = t.clock_jumps();
  if (t.has_surface()) {
    s.has_surface = true;
    s.surface_frame = t.surface().frame_id();
    s.surface_indices.assign(t.surface().indices().begin(), t.surface().indices().end());
    const auto& p = t.surface().positions();
    s.surface_positions.reserve(static_cast<size_t>(p.size() / 3));
    for (int i = 0; i + 2 < p.size(); i += 3)
      s.surface_positions.push_back({p[i], p[i + 1], p[i + 2]});
  }
  return s;
}

void ToProto(const haptics::TissueSurface& s, v1::StationSurface* out) {
  const haptics::SurfaceSpec& spec = s.spec();
  out->mutable_positions()->Reserve(static_cast<int>(3 * spec.positions.size()));
  for (const auto& p : spec.positions)
    for (int i = 0; i < 3; ++i) out->add_positions(static_cast<float>(p[i]));
  out->mutable_triangles()->Reserve(static_cast<int>(3 * spec.triangles.size()));
  for (const auto& t : spec.triangles)
    for (int i : t) out->add_triangles(i);
  for (double k : spec.stiffness) out->add_stiffness(static_cast<float>(k));
  out->set_damping(spec.damping);
  out->set_reach(spec.reach);
  out->set_tissue_stiffness(spec.tissue_stiffness);
  out->set_tissue_damping(spec.tissue_damping);
  for (int i = 0; i < spec.tissue_curve.count; ++i) {
    out->add_tissue_curve_yield(spec.tissue_curve.yield[i]);
    out->add_tissue_curve_force(spec.tissue_curve.force[i]);
  }
  out->set_corners_yield(spec.corners_yield);
}

Expected<std::shared_ptr<const haptics::TissueSurface>> FromProto(const v1::StationSurface& s) {
  if (s.positions_size() % 3 != 0 || s.triangles_size() % 3 != 0)
    return InvalidArgument("surface", "positions and triangles come in threes");
  if (static_cast<size_t>(s.positions_size()) > 3 * haptics::TissueSurface::kMaxVertices ||
      static_cast<size_t>(s.triangles_size()) > 3 * haptics::TissueSurface::kMaxTriangles)
    return InvalidArgument("surface", "the surface is larger than a station takes");
  haptics::SurfaceSpec spec;
  spec.positions.resize(static_cast<size_t>(s.positions_size() / 3));
  for (size_t v = 0; v < spec.positions.size(); ++v)
    for (int i = 0; i < 3; ++i) spec.positions[v][i] = s.positions(static_cast<int>(3 * v) + i);
  spec.triangles.resize(static_cast<size_t>(s.triangles_size() / 3));
  for (size_t t = 0; t < spec.triangles.size(); ++t)
    for (int i = 0; i < 3; ++i) spec.triangles[t][i] = s.triangles(static_cast<int>(3 * t) + i);
  spec.stiffness.assign(s.stiffness().begin(), s.stiffness().end());
  spec.damping = s.damping();
  spec.reach = s.reach();
  spec.tissue_stiffness = s.tissue_stiffness();
  spec.tissue_damping = s.tissue_damping();
  const int points = s.tissue_curve_yield_size();
  if (points != s.tissue_curve_force_size() || points > haptics::TissueCurve::kMaxPoints)
    return InvalidArgument("surface", "the tissue's curve needs as many forces as yields, ≤ 16");
  for (int i = 0; i < points; ++i)
    spec.tissue_curve.yield[i] = s.tissue_curve_yield(i),
    spec.tissue_curve.force[i] = s.tissue_curve_force(i);
  spec.tissue_curve.count = points;
  spec.corners_yield = s.corners_yield();
  return haptics::TissueSurface::Create(std::move(spec));
}

namespace {

void PutLaw(const haptics::PunctureLaw& l, v1::StationNeedle::Law* out) {
  out->set_a1(l.a1), out->set_a2(l.a2), out->set_puncture(l.puncture);
}

haptics::PunctureLaw GetLaw(const v1::StationNeedle::Law& l) {
  return {l.a1(), l.a2(), l.puncture()};
}

void PutVec(const Eigen::Vector3d& v, v1::Vec3* out) {
  out->set_x(v.x()), out->set_y(v.y()), out->set_z(v.z());
}

Eigen::Vector3d GetVec(const v1::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

}  // namespace

void ToProto(const haptics::NeedleTissueSpec& s, v1::StationNeedle* out) {
  out->set_surface_z(s.surface_z), out->set_centre_x(s.centre_x), out->set_centre_y(s.centre_y);
  out->set_half_x(s.half_x), out->set_half_y(s.half_y);
  for (const haptics::NeedleLayer& l : s.layers) {
    v1::StationNeedle::Layer* w = out->add_layers();
    w->set_name(l.name), w->set_thickness(l.thickness);
    PutLaw(l.top, w->mutable_top());
    w->set_friction_static(l.friction_static), w->set_friction_sliding(l.friction_sliding);
    w->set_friction_viscous(l.friction_viscous), w->set_cutting(l.cutting);
    w->set_lateral_stiffness(l.lateral_stiffness);
  }
  out->set_has_target(s.has_target);
  out->set_target_kind(static_cast<uint32_t>(s.target.kind));
  out->set_target_name(s.target.name);
  PutVec(s.target.centre, out->mutable_target_centre());
  PutVec(s.target.axis, out->mutable_target_axis());
  out->set_target_radius(s.target.radius);
  PutLaw(s.target.wall, out->mutable_target_wall());
  out->set_velocity_deadzone(s.velocity_deadzone);
  out->set_stick_stiffness(s.stick_stiffness);
  out->set_max_entry_angle(s.max_entry_angle);
}

Expected<std::shared_ptr<const haptics::NeedleTissueSpec>> FromProto(const v1::StationNeedle& s) {
  if (s.layers_size() > haptics::kMaxNeedleLayers || s.target_kind() > 1)
    return InvalidArgument("needle", "the needle's tissue is larger than a station takes");
  haptics::NeedleTissueSpec spec;
  spec.surface_z = s.surface_z(), spec.centre_x = s.centre_x(), spec.centre_y = s.centre_y();
  spec.half_x = s.half_x(), spec.half_y = s.half_y();
  for (const v1::StationNeedle::Layer& w : s.layers())
    spec.layers.push_back({w.name().substr(0, 64), w.thickness(), GetLaw(w.top()),
                           w.friction_static(), w.friction_sliding(), w.friction_viscous(),
                           w.cutting(), w.lateral_stiffness()});
  spec.has_target = s.has_target();
  spec.target.kind = static_cast<haptics::NeedleTarget::Kind>(s.target_kind());
  spec.target.name = s.target_name().substr(0, 64);
  spec.target.centre = GetVec(s.target_centre());
  spec.target.axis = GetVec(s.target_axis());
  spec.target.radius = s.target_radius();
  spec.target.wall = GetLaw(s.target_wall());
  spec.velocity_deadzone = s.velocity_deadzone();
  spec.stick_stiffness = s.stick_stiffness();
  spec.max_entry_angle = s.max_entry_angle();
  if (Status st = haptics::CheckNeedleTissue(spec); !st.ok()) return st.error();
  return std::make_shared<const haptics::NeedleTissueSpec>(std::move(spec));
}

void ToProto(const haptics::BladeParams& b, v1::StationBlade* out) {
  out->set_toughness(b.toughness);
  out->set_thickness(b.thickness);
  out->set_angle(b.angle);
  out->set_width(b.width);
  out->set_in_plane_stiffness(b.in_plane_stiffness);
  out->set_normal_stiffness(b.normal_stiffness);
  out->set_half_x(b.half_x);
  out->set_half_y(b.half_y);
  out->set_min_segment(b.min_segment);
}

Expected<std::shared_ptr<const haptics::BladeParams>> FromProto(const v1::StationBlade& s) {
  haptics::BladeParams b;
  b.toughness = s.toughness(), b.thickness = s.thickness(), b.angle = s.angle();
  b.width = s.width(), b.in_plane_stiffness = s.in_plane_stiffness();
  b.normal_stiffness = s.normal_stiffness(), b.half_x = s.half_x(), b.half_y = s.half_y();
  b.min_segment = s.min_segment();
  if (Status st = haptics::CheckBlade(b); !st.ok()) return st.error();
  return std::make_shared<const haptics::BladeParams>(b);
}

void ToProto(const scoring::PalpationOutcome& o, v1::PalpationOutcome* out) {
  for (size_t i = 0; i < o.lumps.size(); ++i) {
    v1::PalpationOutcome::Lump* l = out->add_lumps();
    PutVec(o.lumps[i].centre, l->mutable_centre());
    l->set_radius(o.lumps[i].radius);
    PutVec(o.lumps[i].surface, l->mutable_surface());
    l->set_found(i < o.found.size() && o.found[i]);
  }
  for (const scoring::PalpationOutcome::Placed& m : o.marks) {
    v1::PalpationOutcome::Mark* w = out->add_marks();
    PutVec(m.position, w->mutable_position());
    w->set_time_s(m.time);
    w->set_lump(m.lump);
  }
}

scoring::PalpationOutcome FromProto(const v1::PalpationOutcome& o) {
  scoring::PalpationOutcome out;
  std::vector<int> index(static_cast<size_t>(o.lumps_size()), -1);  // wire index → kept index
  for (int i = 0; i < o.lumps_size(); ++i) {
    const v1::PalpationOutcome::Lump& l = o.lumps(i);
    const scoring::Lump lump{GetVec(l.centre()), l.radius(), GetVec(l.surface())};
    if (!lump.centre.allFinite() || !lump.surface.allFinite() || !(lump.radius > 0) ||
        !std::isfinite(lump.radius))
      continue;
    index[static_cast<size_t>(i)] = static_cast<int>(out.lumps.size());
    out.lumps.push_back(lump);
    out.found.push_back(l.found());
  }
  for (const v1::PalpationOutcome::Mark& m : o.marks()) {
    const Eigen::Vector3d at = GetVec(m.position());
    if (!at.allFinite() || !std::isfinite(m.time_s())) continue;
    const int lump = m.lump() >= 0 && m.lump() < o.lumps_size() ? index[m.lump()] : -1;
    out.marks.push_back({at, m.time_s(), lump});
  }
  return out;
}

}  // namespace vsurg::convert
