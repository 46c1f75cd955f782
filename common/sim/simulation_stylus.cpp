// Simulation's haptic path (simulation.h): one stylus sample in, one force command out, on the
// haptic thread at ≥ 1 kHz, never allocating, never blocking. OnStylus is the driver; each stage
// below is one step of it. Also here: what the station renders ahead of the answers (the surface
// ahead of a free tip, and the surface a station gets with its join).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/sim/rooms/room_support.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;
using haptics::ForceCommand;
using haptics::StylusSample;

namespace {
// How far a contact's fitted tissue may stand from the scene's calibrated law (either way, in
// k_t and in b) and still be the tissue rather than a transient (ContactModel).
constexpr double kLawSpread = 4.0;
}  // namespace

// The haptic path, one sample: reject bad input; count the port's energy; advance the trial
// clock and the guidance's ramps; then, on the tool (the trainee's, or shared with an instructor:
// guidance.h), the needle in its tissue, the grasp's twist or the proxy's contact (or the surface
// ahead of a free tip); the
// trainee's share of it; the safety filter, the local model for the station; the trial record and
// the telemetry.
// Flattened: the stages are inlined into the driver, as one function was before them.
[[gnu::flatten]] ForceCommand Simulation::OnStylus(const StylusSample& trainee) {
  StylusStep step;
  if (!safety_.AcceptInput(trainee, step.events)) return RejectInput(trainee, step.events);
  CountPortEnergy(trainee);
  step.dt = AdvanceClock(trainee, step.events);
  guidance_.Advance(trial_time_);
  const StylusSample s = guidance_.Tool(trainee);  // the trainee's own while nobody guides
  surface_.Acquire();
  const Snapshot& snap = surface_.Front();
  const bool button = (s.buttons & haptics::kButtonGrasp) != 0;
  step.cmd.time = s.time;
  step.overload = grasping_ ? grasp_overload_.load(std::memory_order_relaxed) : snap.overload;
  if (grasping_ && !button) {
    EndGrasp(step.events);
    RoomTwistStep(TwistPhase::kRelease, step.dt);
  }
  if (needle_.model) {
    NeedleStep(snap, s, step);
  } else if (cut_.blade) {
    CutStep(s, step);
    SecondHandStep(step.dt);
  } else if (grasping_) {
    GraspStep(s, step);
  } else {
    ContactStep(snap, s, button, step);
  }
  PublishInput();
  PalpationStep(trainee, step);
  ShareTool(trainee, step);
  const Vec3 out = Answer(snap, guidance_.shared() ? trainee : s, step);
  RecordSample(trainee, step, out);
  ++samples_;
  PublishTelemetry(trainee, step.cmd, out, step.quantity);
  step.cmd.score = live_score_;
  return step.cmd;
}

// Input the safety filter refused (NaN, outside the workspace): zero force, let go of
// everything; the next good sample passes the start-up gate again.
ForceCommand Simulation::RejectInput(const StylusSample& s, uint32_t events) {
  if (grasping_) {
    events |= haptics::kEventGraspEnd;
    RoomTwistStep(TwistPhase::kRelease, 1e-3);
  }
  grasping_ = false;
  last_contact_ = false;
  proxy_.Reset();
  safety_.Disarm();
  input_.grasping = false;
  input_.torque = 0;
  input_.triangle = -1;
  input_.force_on_tissue.setZero();
  PublishInput();
  port_force_.setZero();  // nothing is answered: no force is held on the way to the next sample
  return Zero(s, events);
}

// The port's energy: the force answered last, held until this sample, against the motion since.
void Simulation::CountPortEnergy(const StylusSample& s) {
  if (port_has_x_) {
    const double w = port_force_.dot(s.position - port_x_);
    if (std::isfinite(w)) (w > 0 ? released_j_ : absorbed_j_) += std::abs(w);
  }
  port_x_ = s.position;
  port_has_x_ = true;
}

// The trial clock follows the station's time in steps of at most kMaxClockStepS; a longer step
// forward advances it by the bound, a step backwards by a nominal millisecond, and both count as
// clock jumps. A repeated stamp does not advance it. Returns the step the proxy integrates over.
double Simulation::AdvanceClock(const StylusSample& s, uint32_t& events) {
  double step = 0;
  if (has_time_) {
    const double station_dt = s.time - last_time_;  // may overflow to ±inf: still ordered
    if (station_dt >= 0 && station_dt <= kMaxClockStepS) {
      step = station_dt;
    } else {
      step = station_dt > 0 ? kMaxClockStepS : 1e-3;
      events |= haptics::kEventClockJump;
      ++clock_jumps_;
    }
  }
  trial_time_ += step;
  last_time_ = s.time;
  has_time_ = true;
  return step > 0 && step < 0.1 ? step : 1e-3;  // repeated, or after a pause or a jump
}

void Simulation::EndGrasp(uint32_t& events) {
  grasping_ = false;
  events |= haptics::kEventGraspEnd;
  input_.grasping = false;
  input_.torque = 0;
  proxy_.Reset();
}

TwistAnswer Simulation::TwistAt(double phi) {
  return std::visit(
      [&](auto& room) -> TwistAnswer {
        if constexpr (requires { room.Twist(0.0); })
          return room.Twist(phi);
        else
          return {};
      },
      room_);
}

// A room whose torque relaxes (rooms/reduced_twist_room.h) around one sample's twist: the step
// begins (its length and the trial's time), ends at a twist, or the grasp is let go.
void Simulation::RoomTwistStep(TwistPhase phase, double dt, double twist) {
  std::visit(
      [&](auto& room) {
        if constexpr (requires { room.EndTwistStep(0.0); }) {
          if (phase == TwistPhase::kBegin) room.BeginTwistStep(dt, trial_time_);
          if (phase == TwistPhase::kEnd) room.EndTwistStep(twist);
          if (phase == TwistPhase::kRelease) room.ReleaseTwist(dt, trial_time_);
        }
      },
      room_);
}

// A held grasp: the twist about the axis is the twist part of the rotation since the grasp
// (swing–twist); the room's torque answers it, the hold spring keeps the grasped point.
void Simulation::GraspStep(const StylusSample& s, StylusStep& step) {
  const Eigen::Quaterniond rel = s.orientation.normalized() * grasp_q0_.conjugate();
  const double twist =
      std::remainder(2.0 * std::atan2(rel.vec().dot(axis_), rel.w()), 2.0 * std::numbers::pi);
  RoomTwistStep(TwistPhase::kBegin, step.dt);
  const TwistAnswer answer = TwistAt(twist);
  step.overload = step.overload || answer.overload;
  const Vec3 arm = input_.grasp_point - axis_point_;
  const Vec3 turned = axis_point_ + Eigen::AngleAxisd(twist, axis_) * arm;
  const Vec3 radial = turned - axis_point_;
  // A grasp on the axis (the forceps' twist about the surface's normal through the grasped
  // point) pushes along a fixed direction.
  const bool on_axis = !(radial.norm() > 1e-9);
  const Vec3 tangent =
      on_axis ? geometry::AnyPerpendicular(axis_) : Vec3(axis_.cross(radial).normalized());
  const double hold = scene_.haptics.hold_stiffness;
  const double s_f = scene_.haptics.force_scale;
  step.force = s_f * (-answer.torque / lever_) * tangent + hold * (turned - s.position);
  step.jacobian = -hold * Eigen::Matrix3d::Identity();
  GraspModel(s, twist, answer, tangent, on_axis ? Vec3::Zero() : Vec3(radial), step.cmd.local);
  RoomTwistStep(TwistPhase::kEnd, step.dt, twist);
  input_.torque = std::isnan(answer.shape) ? answer.torque : answer.shape;  // the shape's
  step.quantity = twist;
  ForceCommand& cmd = step.cmd;
  cmd.grasping = true;
  cmd.contact = true;
  cmd.proxy = turned;
  cmd.twist = twist;
  cmd.torque = answer.torque;
}

// The grasp's local model for the station. ∂F/∂φ of the grasp force, so the station feels the
// tissue's torsional stiffness dT/dΦ between answers, not only the grip: with r⊥ the radial
// arm's part across the axis, ∂turned/∂φ = a × r = |r⊥|·t and ∂t/∂φ = −r⊥/|r⊥|, hence
//   g = (hold·|r⊥| − s·k_T/lever)·t + s·(T/lever)·r⊥/|r⊥|   (s the force scale);
// and the exact grasp force to render about this answer: the arc, the turning tangent and the
// torque curve around this twist (every room's Twist is a function of the twist alone), so a
// turn of a round trip's size is felt as the server would answer it. `radial` is zero for a
// grasp on the axis (the station then turns nothing).
void Simulation::GraspModel(const StylusSample& s, double twist, const TwistAnswer& answer,
                            const Vec3& tangent, const Vec3& radial, haptics::LocalModel& local) {
  const double hold = scene_.haptics.hold_stiffness;
  const double s_f = scene_.haptics.force_scale;
  const Vec3 across = radial - axis_ * axis_.dot(radial);
  Vec3 g = -s_f * answer.stiffness / lever_ * tangent;
  if (const double r = across.norm(); r > 1e-9)
    g += hold * r * tangent + s_f * answer.torque / lever_ * (across / r);
  local.kind = haptics::LocalModel::Kind::kGrasp;
  local.axis = axis_;
  local.orientation0 = s.orientation.normalized();
  local.dforce_dtwist = g;
  local.has_twist_model = true;
  local.force_per_torque = -s_f / lever_ * tangent;
  local.arm = across;
  local.torque0 = answer.torque;
  for (int i = 0; i < haptics::LocalModel::kTwistSamples; ++i)
    local.torque_steps[i] =
        TwistAt(twist + haptics::LocalModel::kTwistOffsets[i]).torque - answer.torque;
}

// A free or touching tip: the proxy on the published surface. In contact it may start a grasp
// (the button held) and gives the contact's local model; free, the surface ahead.
void Simulation::ContactStep(const Snapshot& snap, const StylusSample& s, bool button,
                             StylusStep& step) {
  const haptics::ProxyState& ps =
      proxy_.Update(snap.positions, snap.bvh, s.position, step.dt, KeptListMotion(snap));
  ForceCommand& cmd = step.cmd;
  if (ps.contact) {
    if (!last_contact_) {
      ++input_.contact_id;
      rest_contact_ = RestPoint(rest_, ps.triangle, ps.barycentric);
      rest_normal_ = geometry::TriangleNormal(rest_, ps.triangle);
    }
    if (button) TryGrasp(ps, s, step.events);
    step.force = ps.force;
    step.jacobian = ps.jacobian;
    const double depth = (rest_contact_ - s.position).dot(rest_normal_);
    ContactModel(ps, depth, step);
    input_.triangle = ps.triangle;
    input_.barycentric = ps.barycentric;
    input_.force_on_tissue = -ps.force;
    input_.hip = s.position;
    if (scene_.task.kind == scoring::TaskKind::kPress) step.quantity = std::max(0.0, depth);
  } else {
    input_.triangle = -1;
    input_.force_on_tissue.setZero();
    SurfaceAhead(snap, s.position, cmd.local, step.jacobian);
  }
  last_contact_ = ps.contact;
  cmd.contact = ps.contact;
  cmd.proxy = ps.scp;
}

// Grasp the point under the proxy, where the tissue model can be grasped.
void Simulation::TryGrasp(const haptics::ProxyState& ps, const StylusSample& s, uint32_t& events) {
  const GraspQuery q{ps.triangle, ps.barycentric, ps.scp, ps.normal, scene_.haptics.min_lever};
  GraspFrame frame;
  const bool grasped = std::visit(
      [&](auto& room) {
        if constexpr (requires { room.StartGrasp(q, frame); })
          return room.StartGrasp(q, frame);
        else
          return false;
      },
      room_);
  if (!grasped) return;
  grasping_ = true;
  grasp_query_ = q;
  events |= haptics::kEventGraspStart;
  ++input_.grasp_id;
  input_.grasping = true;
  input_.grasp_point = ps.scp;
  input_.grasp_vertex = frame.grasp_vertex;
  grasp_q0_ = s.orientation.normalized();
  axis_ = frame.axis;
  axis_point_ = frame.axis_point;
  lever_ = frame.lever;
}

// The contact's local model for the station: the stiffness the contact shows, the tissue model's
// own where it has one (the reduced contact's series stiffness), else fitted to this contact's
// force over its depth; with the viscoelastic model, the tissue under the proxy.
void Simulation::ContactModel(const haptics::ProxyState& ps, double depth, StylusStep& step) {
  const geometry::Triangle& tri = rest_.triangles[ps.triangle];
  const double k_p = proxy_.params().stiffness;
  const auto model = room_has_contact_stiffness_ ? HapticsSpec::ContactModel::kProxy
                                                 : scene_.haptics.contact_model;
  // The fits learn from every sample in contact (else the haptic path pays nothing for them).
  if (model == HapticsSpec::ContactModel::kFitted) {
    if (!last_contact_) stiffness_fit_.BeginContact();
    stiffness_fit_.Add(depth, ps.force.dot(rest_normal_), step.dt);
  }
  // The surface's yield under the proxy along the rest normal: f·n = k_p·(depth − yield).
  const double yield = (rest_contact_ - ps.scp).dot(rest_normal_);
  if (model == HapticsSpec::ContactModel::kViscoelastic) {
    if (!last_contact_) viscoelastic_fit_.BeginContact();
    viscoelastic_fit_.Add(trial_time_, yield, ps.force.dot(rest_normal_), 100 * k_p, 0.05 * k_p);
  }
  if (k_p > 0) step.jacobian *= ContactStiffness({tri, ps.barycentric, rest_normal_, k_p}) / k_p;
  haptics::LocalModel& local = step.cmd.local;
  local.kind = haptics::LocalModel::Kind::kContact;
  local.normal = ps.normal;
  // Until this contact's own fit stands (its first tens of milliseconds), the scene's calibrated
  // law, which the station's surface renders the contact's first round trip with: a first
  // answer without a tissue would be rendered as the proxy's spring alone from its sample, and a
  // round trip into a tap that is millimetres (and a newton) too much. So too for a fit more
  // than kLawSpread from that law: the ringing of a tap's first 50 ms read k_t 16.9 N/m and
  // b 1.13 N·s/m on the ball calibrated at 133 and 13, and such a tissue follows a withdrawing
  // tool at the station with its whole force.
  const haptics::ViscoelasticParams& fit = viscoelastic_fit_.params();
  const haptics::ViscoelasticParams law{scene_.haptics.tissue_stiffness,
                                        scene_.haptics.tissue_damping, 0};
  const auto near = [](double a, double b) {
    return !(b > 0) || (a >= b / kLawSpread && a <= b * kLawSpread);
  };
  const haptics::ViscoelasticParams v =
      fit.ok() && near(fit.stiffness, law.stiffness) && near(fit.damping, law.damping) ? fit : law;
  if (model == HapticsSpec::ContactModel::kViscoelastic && v.ok()) {
    local.tissue_stiffness = v.stiffness;
    local.tissue_damping = v.damping;
    // The tissue's elastic force now: the force along the model's normal (the one the station
    // projects on) less its viscous part at the surface's measured rate. Anything else (the fit's
    // a + k_t·S, the force along the rest normal) differs from the station's f₀ by an error the
    // station would integrate into a creep of error/b over the round trip. The viscous part at
    // most half the force (the station bounds it so too).
    const double f_n = ps.force.dot(ps.normal);
    local.tissue_elastic0 = f_n - std::clamp(v.damping * viscoelastic_fit_.rate(),
                                             -0.5 * std::abs(f_n), 0.5 * std::abs(f_n));
  }
}

// The device limits on the force and on the local model, and the answer's events.
Vec3 Simulation::Answer(const Snapshot& snap, const StylusSample& s, StylusStep& step) {
  ForceCommand& cmd = step.cmd;
  const Vec3 out = safety_.Filter(step.force, step.dt, step.events);
  cmd.force = out;
  port_force_ = out;
  cmd.released_j = released_j_;
  cmd.absorbed_j = absorbed_j_;
  if (cmd.local.kind != haptics::LocalModel::Kind::kContact || cmd.contact)
    cmd.local.position0 = s.position;  // else SurfaceAhead placed it on the surface
  cmd.local.jacobian = step.jacobian;
  safety_.LimitLocalModel(cmd.local, out, step.events);
  if (step.overload) step.events |= haptics::kEventOverload;
  const bool outside =
      cmd.grasping ? grasp_outside_model_.load(std::memory_order_relaxed) : snap.outside_model;
  if (outside && cmd.contact) step.events |= haptics::kEventOutsideModel;
  cmd.events = step.events;
  return out;
}

// Telemetry for instructors (30 Hz): every 8th sample is plenty at ≥ 1 kHz and keeps the metrics
// summary off most haptic cycles. Never allocates (TrialMetrics is plain data).
void Simulation::PublishTelemetry(const StylusSample& s, const ForceCommand& cmd, const Vec3& out,
                                  double quantity) {
  if (!((samples_ & 7) == 1 || cmd.grasping != telemetry_grasping_)) return;
  telemetry_grasping_ = cmd.grasping;
  Telemetry& t = telemetry_.Back();
  t.time = s.time;
  t.force = out;
  t.tip = s.position;
  t.twist = cmd.twist;
  t.torque = cmd.torque;
  t.depth = scene_.task.kind == scoring::TaskKind::kPress ||
                    scene_.task.kind == scoring::TaskKind::kInsert
                ? quantity  // a press's depth, a needle's along its tract
                : 0;
  t.contact = cmd.contact;
  t.grasping = cmd.grasping;
  t.samples = samples_;
  t.clock_jumps = clock_jumps_;
  t.guide_mode = static_cast<uint32_t>(guidance_.mode());
  t.guide_alpha = guidance_.alpha();
  t.instructor = guidance_.engaged();
  t.instructor_tip = guidance_.instructor().position;
  t.hands_apart = t.instructor ? (t.instructor_tip - s.position).norm() : 0.0;
  t.tool = guidance_.Tool(s).position;
  t.tool_force = tool_force_;
  t.metrics = Metrics();
  // A palpation's score says whether the marks found the lumps: the trainee sees it only when
  // the search is over (the instructor's telemetry has it all along).
  // So does a needle's, whether its tip is in the target.
  live_score_ = scene_.task.kind == scoring::TaskKind::kPalpate ||
                        scene_.task.kind == scoring::TaskKind::kInsert
                    ? 0.0
                    : t.metrics.score;
  telemetry_.Publish();
}

ForceCommand Simulation::Zero(const StylusSample& s, uint32_t events) {
  ForceCommand c;
  c.time = std::isfinite(s.time) ? s.time : last_time_;
  c.events = events;
  c.local.position0 = s.position.allFinite() ? s.position : Vec3::Zero();
  c.released_j = released_j_;
  c.absorbed_j = absorbed_j_;
  return c;
}

// The surface ahead of contact (model-mediated teleoperation, Mitra & Niemeyer 2008): for a free
// tip within the scene's lookahead, the plane of the nearest surface point with the stiffness the
// contact would have there, F(x) = k·((p − x)·n)·n on the penetrating side only. The station then
// begins the contact where the surface is, whatever the delay.
void Simulation::SurfaceAhead(const Snapshot& snap, const Vec3& tip, haptics::LocalModel& local,
                              Eigen::Matrix3d& jacobian) {
  const double reach = scene_.haptics.lookahead;
  if (!(reach > 0) || !tip.allFinite()) return;
  const geometry::ClosestHit c =
      ahead_cache_.Closest(snap.bvh, snap.positions, KeptListMotion(snap), tip, reach, Vec3::Zero(),
                           -2.0, ahead_triangle_);
  ahead_triangle_ = c.triangle;
  if (c.triangle < 0) return;
  const geometry::Triangle& tri = rest_.triangles[c.triangle];
  const Vec3 n = geometry::TriangleNormal(snap.positions, tri);
  if (!n.allFinite() || (tip - c.point).dot(n) < 0) return;  // behind the face: not ahead of it
  double k = proxy_.params().stiffness;
  if (k > 0) {
    const Vec3 rest_normal = geometry::TriangleNormal(rest_, c.triangle);
    k = ContactStiffness({tri, c.barycentric, rest_normal, k});
  }
  local.kind = haptics::LocalModel::Kind::kContact;
  local.normal = n;
  local.position0 = c.point;
  local.contact_damping = proxy_.params().damping;
  jacobian = -k * n * n.transpose();
}

// What a station renders ahead of the server's answers (haptics/tissue_surface.h): the surface
// at rest, and at each vertex the stiffness SurfaceAhead would give a tip nearest to it. Null when
// the scene renders no surface ahead (lookahead 0), the proxy has no stiffness, or the scene does
// not send one (HapticsSpec::StationSurface).
std::shared_ptr<const haptics::TissueSurface> Simulation::MakeStationSurface() const {
  const double kp = proxy_.params().stiffness;
  if (!(scene_.haptics.lookahead > 0) || !(kp > 0) ||
      !scene_.haptics.StationSurface(scene_.task.kind))
    return nullptr;
  haptics::SurfaceSpec spec;
  spec.positions = rest_.positions;
  spec.triangles = rest_.triangles;
  spec.stiffness.assign(rest_.positions.size(), -1);
  spec.damping = proxy_.params().damping;
  spec.reach = scene_.haptics.lookahead;
  // The tissue's law where the contact renders it (not a reduced contact's own series stiffness).
  if (!room_has_contact_stiffness_ &&
      scene_.haptics.contact_model == HapticsSpec::ContactModel::kViscoelastic) {
    spec.tissue_stiffness = scene_.haptics.tissue_stiffness;
    spec.tissue_damping = scene_.haptics.tissue_damping;
    spec.tissue_curve = scene_.haptics.tissue_curve;
    // The mass-spring contact anchors the face's corners, each by its barycentric weight.
    spec.corners_yield = std::holds_alternative<MassSpringRoom>(room_);
  }
  for (int t = 0; t < rest_.TriangleCount(); ++t) {
    const geometry::Triangle& tri = rest_.triangles[t];
    const Vec3 rest_normal = geometry::TriangleNormal(rest_, t);
    for (int i = 0; i < 3; ++i) {
      if (spec.stiffness[tri[i]] >= 0) continue;
      const Vec3 corner = Vec3::Unit(i);
      spec.stiffness[tri[i]] = ContactStiffness({tri, corner, rest_normal, kp});
    }
  }
  for (double& k : spec.stiffness)
    if (k < 0) k = kp;  // a vertex no triangle uses: never the nearest point
  auto surface = haptics::TissueSurface::Create(std::move(spec));
  return surface.ok() ? *surface : nullptr;
}

// The slope of the contact's force over the tool's depth for the station's local model: the
// room's own (a reduced contact's series stiffness), else the fitted one within [0.1, 1]·k_p
// (a tissue that yields is softer than the proxy, never stiffer), else the proxy's k_p.
double Simulation::ContactStiffness(const ContactQuery& q) const {
  double k = q.proxy_stiffness;
  bool own = false;
  std::visit(
      [&](const auto& room) {
        if constexpr (requires { room.ContactStiffness(q); }) {
          k = room.ContactStiffness(q);
          own = true;
        }
      },
      room_);
  if (!own && scene_.haptics.contact_model == HapticsSpec::ContactModel::kFitted)
    k = stiffness_fit_.Stiffness(0.1 * q.proxy_stiffness, q.proxy_stiffness, q.proxy_stiffness);
  return k;
}

}  // namespace vsurg::sim
