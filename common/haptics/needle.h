// A needle through layered tissue (DESIGN.md "Needle insertion"): the force on a needle's tip
// from a skin surface, the layers under it and a target (a vessel or a cyst), in the form of
// Okamura, Simone & O'Leary (IEEE TBME 2004, "Force modeling for needle insertion into soft
// tissue"): the force along the needle is
//
//   f(s) = f_stiffness(w)                 a boundary not yet punctured, pressed by w (m):
//                                         a1·w + a2·w² (their eq. for the capsule's stiffness),
//                                         until it reaches the layer's puncture force: the "pop"
//        + f_friction(ṡ)                  Karnopp's friction on the shaft in punctured tissue
//        + f_cutting                      the tip advancing through tissue not yet cut
//
// and, across the needle, the tissue holds the shaft: the tip's distance from its tract is
// resisted by a spring that grows with the shaft's length in each layer.
//
// Rendered at an impedance device, the two laws that stick are springs to a moving point:
//   friction   the shaft sticks to an anchor on the tract, f = −k_s·(s − anchor), until |f|
//              exceeds Karnopp's limit (the static force D inside the velocity dead zone |ṡ| ≤ Δv,
//              else C + b·|ṡ|), when the anchor slides to keep |f| at the limit;
//   cutting    the tip's front, f = −k_s·(s − cut) while the tip is past the depth cut so far,
//              up to the layer's cutting force, when the front advances (the tissue is cut).
// Both are passive (the anchor and the front dissipate whatever the hand puts into them beyond
// the spring), and both are continuous: the device's rate limit never sees a step but the pop.
//
// Geometry: the skin is the plane z = surface_z of the scene's frame, within a rectangle; the
// layers lie parallel under it, each its thickness thick; the target is a cylinder (a vessel)
// along an axis or a sphere (a cyst), with a wall of its own stiffness and puncture force. A
// tract starts where the tip crosses the skin, along the needle's axis then, and is a straight
// line: the boundaries along it (the layers' planes and the target's walls) are found once, at
// the start, and the tip's depth s along it orders everything after.
//
// Withdrawal and reinsertion: a needle drawn out of the skin leaves its tract (its entry, its
// direction, the boundaries it punctured and the depth it cut); a later entry within
// kReuseRadius of that entry and kReuseAngle of its direction follows it, feeling only the
// friction up to the depth cut before; any other entry is a new path and punctures afresh.
//
// Redirection without leaving the skin (what a clinician does after a miss: draw back into the
// subcutaneous layer, angle, advance again): with its tip drawn back above the second boundary
// under the skin (in the skin or the layer right under it, where only those hold the shaft), a
// needle turned more than kRedirectAngle from its tract, its tip carried off the old line by at
// least kRedirectOffset, pivots about the skin's hole as soon as it advances (a step of at least
// kRedirectAdvance along its axis: turned in place, it has cut nothing new). The tract is left
// (remembered as a withdrawn one is) and a new one begins at the same entry along the needle's
// axis, the skin and the layer the tip is in already open, every boundary beyond punctured afresh;
// turned back onto an earlier tract from that entry, the needle follows it again. Deeper, the
// tissue holds the needle on its tract (the lateral spring) and turning it only strains the tissue.
//
// The same model runs at the server (authoritative) and at the station (sent with the join;
// the server's answers carry NeedleState), so a pop is felt on the cycle the hand's force
// crosses the puncture force whatever the delay.
//
// Units: m, s, N, N/m, N/m² (a2; also per metre of shaft: N/m per m), N·s/m². No allocation per
// step; one model per thread.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/haptics/types.h"

namespace vsurg::haptics {

// A boundary's stiffness before it gives way: f = a1·w + a2·w² up to the puncture force.
struct PunctureLaw {
  double a1 = 0;        // N/m
  double a2 = 0;        // N/m²
  double puncture = 0;  // N
  double At(double w) const { return w > 0 ? (a1 + a2 * w) * w : 0.0; }
};

// One layer, from the skin down; its top is the boundary it is entered by.
struct NeedleLayer {
  std::string name;
  double thickness = 0;  // m; the last layer goes on to the bottom
  PunctureLaw top;       // its upper boundary (the skin's, for the first)
  // Karnopp's friction per metre of shaft in this layer (N/m): the static limit D, the sliding
  // force C, and the viscous b (N·s/m²).
  double friction_static = 0, friction_sliding = 0, friction_viscous = 0;
  double cutting = 0;            // N, at a tip advancing through this layer uncut
  double lateral_stiffness = 0;  // N/m per metre of shaft: the tissue holding the needle
};

struct NeedleTarget {
  enum class Kind : uint32_t { kVessel = 0, kCyst = 1 };
  Kind kind = Kind::kVessel;
  std::string name = "vessel";
  Vec3 centre = Vec3::Zero();  // m
  Vec3 axis = Vec3::UnitY();   // a vessel's axis (unit)
  double radius = 0.004;       // m, inside the wall
  PunctureLaw wall;            // front and back alike
};

struct NeedleTissueSpec {
  double surface_z = 0;                 // m, the skin's plane (normal +z)
  double centre_x = 0, centre_y = 0;    // m, the skin rectangle's centre
  double half_x = 0.05, half_y = 0.05;  // m, its half sizes
  std::vector<NeedleLayer> layers;      // 1..kMaxLayers, from the skin down
  bool has_target = false;
  NeedleTarget target;
  double velocity_deadzone = 0.002;  // m/s, Karnopp's Δv
  double stick_stiffness = 300;      // N/m, k_s of the friction's anchor and the cutting front
  // A needle flatter to the skin than this (rad from the normal) slides on it and does not enter.
  double max_entry_angle = 1.309;  // 75°
};

inline constexpr int kMaxNeedleLayers = 6;

// Checks every field by name (layers[1].top.puncture: must be > 0 …).
Status CheckNeedleTissue(const NeedleTissueSpec& spec);

// Where a boundary along a tract leads.
enum class NeedleMedium : int32_t { kLumen = -1 };  // else a layer's index

struct NeedleBoundary {
  double depth = 0;  // m along the tract from its entry
  PunctureLaw law;
  int32_t after = 0;  // the medium beyond it: a layer's index, or NeedleMedium::kLumen
  uint32_t role = 0;  // kRole bits
  static constexpr uint32_t kRoleTargetFront = 1, kRoleTargetBack = 2;
};

// One step's answer.
struct NeedleForce {
  Vec3 force = Vec3::Zero();  // N, on the needle's tip (to the hand)
  bool popped = false;        // a boundary gave way at this step
  bool entered_target = false, breached_back_wall = false;
  bool in_tissue = false;    // touching the skin or inserted
  double depth = 0;          // m, the tip along the tract (0 when free)
  double lateral = 0;        // m, the tip's distance from its tract
  double strain = 0;         // the tract's lateral strain: lateral over the shaft held (≥ 0)
  bool in_target = false;    // the tip inside the target's lumen
  bool redirected = false;   // the tract turned about the skin's hole at this step
  double cutting_force = 0;  // N, the cutting part (≥ 0), for records
};

class NeedleModel {
 public:
  static constexpr int kMaxBoundaries = kMaxNeedleLayers + 2;
  static constexpr int kMaxTracts = 8;               // earlier tracts remembered for reinsertion
  static constexpr double kReuseRadius = 1.5e-3;     // m
  static constexpr double kReuseAngle = 0.0873;      // rad, 5°
  static constexpr double kVelocityTau = 0.01;       // s, the velocity's low pass
  static constexpr double kRedirectAngle = 0.1745;   // rad, 10°
  static constexpr double kRedirectOffset = 0.5e-3;  // m
  static constexpr double kRedirectAdvance = 1e-6;   // m per step

  static Expected<NeedleModel> Create(NeedleTissueSpec spec);

  // The tip at `tip`, the needle advancing along `axis` (unit, hub to tip), `dt` s after the
  // previous step. Never allocates. A non-finite input answers zero and changes nothing.
  NeedleForce Step(const Vec3& tip, const Vec3& axis, double dt);

  const NeedleState& state() const { return state_; }
  // Takes a state (the server's answer, or a restored session's): the tract's boundaries are
  // found again from its entry and direction. A state of an unknown tract number is remembered
  // as the newest; the earlier tracts known here stay.
  void Adopt(const NeedleState& s);
  const NeedleTissueSpec& spec() const { return spec_; }
  // The boundaries along the current tract (valid while inserted or touching).
  int boundary_count() const { return count_; }
  const NeedleBoundary& boundary(int i) const { return bounds_[i]; }
  // The target as the current tract meets it: `middle`, the depth along the tract nearest the
  // target's centre (a cyst) or axis (a vessel), halfway between its walls where the tract
  // crosses them; `deviation`, the tract's distance from that centre or axis (m); `needed`, the
  // boundaries before `middle` (what the tract must puncture to reach it). False when there is
  // no target or no tract.
  bool TargetOnTract(double& middle, double& deviation, int& needed) const;
  // The tracts left in the tissue so far (set-up and reports, not the haptic path): the ones
  // remembered and the current one, oldest first.
  std::vector<NeedleState> Tracts() const;
  // Punctures so far (every boundary given way, reinsertions along a tract not counted again).
  uint32_t punctures() const { return punctures_; }

  // Whole, with the tract memory (live migration).
  template <class A>
  void Persist(A& a) {
    a(state_, punctures_, memory_count_);
    for (auto& m : memory_) a(m);
  }
  // After a read: false when the bytes made no state this model could be in (the caller
  // discards the model); else the boundaries are found again.
  bool Restored();

 private:
  explicit NeedleModel(NeedleTissueSpec spec) : spec_(std::move(spec)) {}
  void FindBoundaries();
  bool Touch(const Vec3& tip, const Vec3& axis);
  NeedleForce Touching(const Vec3& tip, const Vec3& u);
  NeedleForce Inserted(const Vec3& tip, double dt, bool may_pop);
  bool Redirect(const Vec3& tip, const Vec3& u);
  bool Follow(const Vec3& entry, const Vec3& u, const Vec3& tip);
  double ShaftLaws(double held, double& lateral_k, double& coulomb, double& viscous) const;
  double Friction(double depth, double held, double dt, double& lateral_k);
  void Remember();

  NeedleTissueSpec spec_;
  NeedleState state_;
  std::array<NeedleBoundary, kMaxBoundaries> bounds_{};
  int count_ = 0;
  uint32_t punctures_ = 0;
  std::array<NeedleState, kMaxTracts> memory_{};
  uint32_t memory_count_ = 0;
  Vec3 last_tip_ = Vec3::Constant(0);
  bool has_last_tip_ = false;
};

}  // namespace vsurg::haptics
