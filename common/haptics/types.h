// What crosses the haptic boundary: a stylus sample in, a force command out.
//
// Units: s, m, N, N/m, rad, N·m. Positions are in the scene frame. These are plain values; the
// network layer (proto/) converts them to and from its wire messages.
#pragma once

#include <array>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vsurg::haptics {

using Vec3 = Eigen::Vector3d;

enum StylusButton : uint32_t {
  kButtonGrasp = 1u << 0,  // held: grasp (and twist) the tissue under the tip
  kButtonMark = 1u << 1,   // pressed on the surface: a palpation's mark ("a lump here")
};

struct StylusSample {
  double time = 0;                                                  // s, the station's clock
  Vec3 position = Vec3::Zero();                                     // m, the tip (HIP)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // stylus frame in scene frame
  uint32_t buttons = 0;                                             // StylusButton bits
};

// A needle's state in its tissue (haptics/needle.h): what the server's answers carry to the
// station (LocalModel::needle), and what live migration carries between nodes. Units: m, m/s.
struct NeedleState {
  enum class Phase : uint32_t { kFree = 0, kTouching = 1, kInserted = 2 };
  Phase phase = Phase::kFree;
  uint32_t tract = 0;               // the tract's number (the n-th begun); 0: none yet
  uint32_t begun = 0;               // tracts begun so far (the next new one is begun + 1)
  Vec3 entry = Vec3::Zero();        // m, where the tract crosses the skin
  Vec3 direction = -Vec3::UnitZ();  // unit, into the tissue
  uint32_t passed = 0;              // boundaries punctured along the tract (the skin is the first)
  double cut = 0;                   // m, the depth cut along the tract
  double anchor = 0;                // m, the friction's stick point along the tract
  double last_depth = 0;            // m, the previous step's depth (the velocity)
  double velocity = 0;              // m/s along the tract, low-passed
  template <class A>
  void Persist(A& a) {
    a(phase, tract, begun, entry, direction, passed, cut, anchor, last_depth, velocity);
  }
  bool operator==(const NeedleState&) const = default;
};

// What a station renders between server updates, so that the force follows the hand at the
// device's rate whatever the network's delay (OpenSurgSim's virtual coupler sends the linear
// part; model-mediated teleoperation, Mitra & Niemeyer 2008, the rest):
//
//   linear   F(x) = force0 + J·(x − position0), everywhere (the first linear model);
//   contact  the same, but unilateral: zero wherever n·F(x) ≤ 0, i.e. once the tool has left the
//            local surface (normal n, outward). Sent in contact (F₀ the force, J the tissue's
//            stiffness behind the proxy) and ahead of contact (position0 the nearest surface
//            point, F₀ = 0, J = −k n nᵀ), so contact begins and ends at the station at the right
//            place and depth whatever the delay;
//   grasp    while the station's own grasp button is held: F(x, φ) = force0 + J·(x − position0)
//            + g·Δφ, Δφ the stylus's twist about `axis` since `orientation0` (swing–twist, the
//            server's own measure) and g = ∂F/∂φ (N/rad), which carries the tissue's torsional
//            stiffness dM/dΦ; zero from the cycle the button is released. A grasp may carry
//            the server's exact grasp force instead (has_twist_model, below): the arc, the turning
//            tangent and the torque curve, so a turn of a round trip's size is felt as it is.
//
// A contact may also carry the tissue under the proxy (tissue_stiffness > 0): the station then
// renders the normal force of the proxy's spring in series with a Kelvin–Voigt tissue point,
// integrated over its own motion since the answered sample (haptics/viscoelastic.h), so a
// stale answer's force follows the tissue's yield and recovery, not one slope.
struct LocalModel {
  // kNeedle: the needle's state in its tissue; a station that holds the tissue (from its join)
  // renders it with its own NeedleModel, the answers correcting its tract and punctures
  // (haptics/needle.h); one that does not renders force0.
  enum class Kind : uint32_t { kLinear = 0, kContact = 1, kGrasp = 2, kNeedle = 3 };  // wire values
  Vec3 force0 = Vec3::Zero();                                                         // N
  Vec3 position0 = Vec3::Zero();                                                      // m
  Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();  // N/m, ∂F/∂x (negative semi-definite)
  Kind kind = Kind::kLinear;
  Vec3 normal = Vec3::UnitZ();  // contact: the surface's outward unit normal
  Vec3 axis = Vec3::UnitZ();    // grasp: the twist axis (unit)
  Eigen::Quaterniond orientation0 = Eigen::Quaterniond::Identity();  // grasp: stylus at position0
  Vec3 dforce_dtwist = Vec3::Zero();                                 // grasp: g, N/rad
  // Grasp, exactly (has_twist_model): the server's own grasp force, F(x, φ) = −c·T(φ)·t(φ) +
  // hold·(turned(φ) − x), turned(φ) the grasped point carried round the axis and t(φ) its
  // tangent. Rendered about the answer as F = force0 + J·(x − x₀) − J·(R − I)·r + T₀·(R − I)·u +
  // ΔT(Δφ)·R·u, R the turn by Δφ about `axis`, so a hand that turns tens of degrees in a round
  // trip feels the arc and the torque curve, not their tangents (g·Δφ is this to first order).
  // r: the grasped point's arm from the axis, across it (m; zero for a grasp on the axis, whose
  // force keeps its direction: u is then not turned); u = −c·t(φ₀) (N per N·m, c the
  // force scale over the lever); T₀ = T(φ₀) (N·m); torque_steps[i] = T(φ₀ + kTwistOffsets[i]) −
  // T(φ₀) (N·m), the tissue's torque curve around the answer's twist.
  static constexpr int kTwistSamples = 8;
  static constexpr std::array<double, kTwistSamples> kTwistOffsets = {-1.0, -0.4, -0.15, -0.05,
                                                                      0.05, 0.15, 0.4,   1.0};
  bool has_twist_model = false;
  std::array<double, kTwistSamples> torque_steps{};
  Vec3 force_per_torque = Vec3::Zero();
  Vec3 arm = Vec3::Zero();
  double torque0 = 0;
  double tissue_stiffness = 0;  // contact: k_t, N/m; 0: the proxy's spring J alone
  double tissue_damping = 0;    // contact: b, N·s/m
  double tissue_elastic0 = 0;   // contact: e₀, N, the tissue's elastic force at position0
  // Contact ahead of the tool (the surface the server's proxy has not reached): the proxy's
  // damping c (N·s/m), which the station adds along n with its own velocity once the tip is in,
  // so an impact it renders before any answer is as dissipative as the server's proxy would make
  // it (F·n = k·depth − c·v·n, never below 0). 0 in a contact answer, whose force0 already holds
  // the server's damping at its sample.
  double contact_damping = 0;
  NeedleState needle;  // kNeedle
  // A shared tool's coupling (four-handed training, sim/guidance.h): the other hand's tool
  // `pull_target` (m) pulls this one by pull_gain·c(pull_target − x), c = CouplingPull, which J
  // leaves out: its cap is not linear, and a hand a round trip behind would feel k_c times its
  // own lag on top of a pull the server held at the cap. 0: no coupling.
  Vec3 pull_target = Vec3::Zero();
  double pull_gain = 0;

  // force0 + J·(x − x₀), plus the coupling's change from x₀ to x when it has one.
  Vec3 ForceAt(const Vec3& x) const;
  // The force the model gives a stylus at x, moving at v (m/s, the station's own estimate), turned
  // to q, with `buttons` held (the kinds above). Any thread; no allocation; a non-finite result
  // is zero.
  Vec3 Render(const Vec3& x, const Eigen::Quaterniond& q, uint32_t buttons,
              const Vec3& v = Vec3::Zero()) const;
  // A grasp's twist, rendered by a 3-DoF device, is a force field F_φ that grows with the
  // stylus's turn; a hand yielding to it against the hold spring k (J = −k·I) is given up to
  // |F_φ|²/(2k), F_φ the model's force at the hold spring's centre (the grasped point `centre`).
  // That energy comes from the hand's own turn, which the device cannot feel: the passivity
  // controller allows it (client/net/passivity.h). J, other kinds, the button up: 0. In J.
  double TwistFieldEnergy(const Vec3& centre, const Eigen::Quaterniond& q, uint32_t buttons) const;
  // Grasp: ΔT(Δφ), the torque curve's change from the answer's twist, piecewise linear through
  // (0, 0) and the samples, extended by the end segments' slopes. N·m.
  double TorqueStep(double dphi) const;
};

// The coupling between two hands on a shared tool (four-handed training): c(d) = k_c·d up to a
// pull of kMaxPull (a hand far from the tool is led, not yanked: 1 cm reaches it). N for d in m.
inline constexpr double kCouplingStiffness = 150;  // N/m, k_c: soft beside a Touch's 400
inline constexpr double kMaxPull = 1.5;            // N
Vec3 CouplingPull(const Vec3& d);

// Safety and interaction events, as bits (several may be set by one sample).
enum HapticEvent : uint32_t {
  kEventNonFiniteInput = 1u << 0,    // the sample had NaN or infinite values: zero force
  kEventOutOfWorkspace = 1u << 1,    // the tip left the device workspace: zero force
  kEventForceClamped = 1u << 2,      // the requested force exceeded the device maximum
  kEventRateLimited = 1u << 3,       // the force changed faster than the device allows
  kEventGated = 1u << 4,             // output held at zero until the request stays small (start-up)
  kEventStiffnessClamped = 1u << 5,  // the local model was stiffer than the device allows
  kEventOverload = 1u << 6,          // the tissue was loaded past its capacity (coil model)
  kEventGraspStart = 1u << 7,
  kEventGraspEnd = 1u << 8,
  // The station's clock jumped (forward by more than sim::kMaxClockStepS, or backwards): the
  // session's trial clock advanced by at most that bound, so one sample's work stays bounded.
  kEventClockJump = 1u << 9,
  // The contact is where the reduced model has no precomputed response (e.g. next to the fixed
  // support): the nearest precomputed contact answered, so the force is bounded but less exact.
  kEventOutsideModel = 1u << 10,
  // Not a force: the session has moved to another node (live migration), and this node answers
  // its station only to say so (zero force, nothing else meant). The station asks where it runs.
  kEventSessionMoved = 1u << 11,
  // A palpation's mark was placed at the proxy (the mark button pressed in contact), or a needle's
  // tip was confirmed inside its target.
  kEventMarked = 1u << 12,
  // A needle punctured a boundary (the skin, a layer, a target's wall): the "pop".
  kEventPunctured = 1u << 13,
  // … and that boundary was the target's back wall: through and through.
  kEventBackWall = 1u << 14,
};

struct ForceCommand {
  double time = 0;            // s, the sample's time echoed
  Vec3 force = Vec3::Zero();  // N, after the device limits
  LocalModel local;           // consistent with `force` at the sample position
  bool contact = false;       // the proxy is on the surface
  bool grasping = false;
  Vec3 proxy = Vec3::Zero();  // m, surface contact point (the tip when free)
  double twist = 0;           // rad, imposed twist while grasping
  double torque = 0;          // N·m, the tissue's answer to it
  double score = 0;           // 0–10, the trial's score so far (updated every few samples)
  uint32_t events = 0;        // HapticEvent bits
  // The server's port of the network two-port (Ryu & Artigas): the energy its force has given
  // the tool and taken from it in this session, Σ F_k·(x_{k+1} − x_k) over the samples it
  // received by sign (J, cumulative, never decreasing). A passive tissue takes at least what it
  // gives back; the station's network passivity lets the hand be given no more than released_j.
  double released_j = 0, absorbed_j = 0;
  // Four-handed training (sim/guidance.h): the session's guidance mode (sim::GuideMode's value)
  // and dominance α now; `shared`, the answer is a shared tool's: render `local` as a linear
  // model only (no contact of the station's own, whose tip is not where the tool is).
  uint32_t guide_mode = 0;
  double guide_alpha = 0;
  bool shared = false;
};

}  // namespace vsurg::haptics
