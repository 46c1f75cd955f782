// A blade through a thin tissue (DESIGN.md "Cutting"): the force a scalpel meets, in the
// fracture-mechanics form of Mahvash & Hayward ("Haptic rendering of cutting: a fracture
// mechanics approach", Haptics-e 2(3), 2001): the tissue first deforms elastically under the
// blade, and the crack advances only when the work the blade does can pay for the new crack's
// surface, J_c per unit area (the fracture toughness); then the force is what that work costs.
//
// In the tissue's frame (the patch in the plane z = 0, its normal +z, the blade's tip at p):
//
//   pressing    the tip below the surface by w, not yet through: f = k_n w along +z (k_n the
//               patch's out-of-plane stiffness) until the stored energy ½ k_n w² reaches the
//               work of opening a crack the blade's width b across the edge's contact length
//               t / cos θ (θ the edge's inclination from the normal): the puncture force
//                 f_p = √(2 k_n J_c t b / cos θ)
//   through     in the plane, the tip's distance d from the crack (the nearest point q of the
//               crack's path, less the slit's half width b/2) is resisted by the tissue beside
//               the crack, f = −k_t d (q − p)/|q − p| ... toward q, until it reaches the force
//               at which the crack advances: the energy balance f·dx = J_c t dx gives
//                 f_c = J_c t
//               and the crack grows from q toward the tip by whatever keeps f at f_c.
//
// The angle changes only the puncture: a frictionless blade drawn through a sheet opens t of
// crack area per metre whatever its inclination (the slice-push reduction of Atkins, Xu &
// Jeronimidis 2004 comes from friction, which this model does not render). The crack's path is
// kept as segments (at least min_segment long; a straight run is one segment), so the blade
// back in its own slit meets no force, and pushed sideways out of it begins a branch at f_c. A
// blade that reaches another part of its cut while loading its front (a circle closing on its
// start) cuts the ligament left between them.
//
// Parameters (scenes/pattern-cut.json): J_c = 1.7 kJ/m² (rat skin, scissors cutting test:
// Pereira, Lucas & Swee-Hin, J. Biomech. 30(1), 1997), t = 1.2 mm; k_t and k_n are the patch's
// own (tissue::CutMembrane), so the deformation phase is the tissue's, not a constant.
//
// Units: m, N, N/m, J/m². No allocation per step; one model per thread.
#pragma once

#include <array>
#include <cstdint>

#include "common/core/expected.h"
#include "common/haptics/types.h"

namespace vsurg::haptics {

struct BladeParams {
  double toughness = 1700;              // J/m², J_c
  double thickness = 1.2e-3;            // m, t
  double angle = 0;                     // rad, θ: the edge's inclination from the normal, < 80°
  double width = 0.3e-3;                // m, b: the edge's width where it meets fresh tissue
  double in_plane_stiffness = 1500;     // N/m, k_t
  double normal_stiffness = 30;         // N/m, k_n
  double half_x = 0.04, half_y = 0.04;  // m, the patch's half sizes (centred on the origin)
  double min_segment = 0.25e-3;         // m
};

// Each field by name: "toughness: must be > 0 J/m²", "width: must be > 0 m" …
Status CheckBlade(const BladeParams& p);

struct BladeForce {
  Vec3 force = Vec3::Zero();  // N, on the blade (to the hand)
  bool through = false;       // the blade is through the tissue
  bool punctured = false;     // it went through at this step
  bool cutting = false;       // the crack advanced at this step
  double advance = 0;         // m, the crack's growth at this step
};

class BladeModel {
 public:
  static constexpr int kMaxSegments = 2048;
  struct Segment {
    double ax, ay, bx, by;  // m, in the tissue's plane
  };

  static Expected<BladeModel> Create(const BladeParams& p);

  // The tip at `tip` (the tissue's frame). A non-finite tip answers zero and changes nothing.
  BladeForce Step(const Vec3& tip);

  double PunctureForce() const;  // N, f_p
  double CuttingForce() const;   // N, f_c
  // m: how far ahead of its front a cutting blade runs (the tissue's stretch at f_c, and the
  // slit's half width).
  double Reach() const;
  double CrackLength() const { return length_; }
  int segment_count() const { return count_; }
  const Segment& segment(int i) const { return segments_[i]; }
  bool through() const { return through_; }
  const BladeParams& params() const { return p_; }

 private:
  explicit BladeModel(const BladeParams& p) : p_(p) {}
  // The crack's point nearest (x, y) and its segment; -1 when there is no crack yet.
  int Nearest(double x, double y, double& qx, double& qy) const;
  void CutLigament(const Vec3& tip, int seg, double qx, double qy);
  void Grow(double qx, double qy, double cx, double cy);
  BladeForce Press(const Vec3& tip);
  BladeForce Draw(const Vec3& tip);

  BladeParams p_;
  bool through_ = false;
  std::array<Segment, kMaxSegments> segments_{};
  int count_ = 0;
  double length_ = 0;
};

// What a blade's crack grew by since it was last asked, each piece once and in order: the
// pieces a cuttable tissue is to carve. The last segment may grow again, so it is resumed from
// where it was left. `grow(ax, ay, bx, by)` returns false to stop; that piece is offered again
// next time (a full queue loses nothing).
class CrackFeed {
 public:
  template <class F>
  void Take(const BladeModel& blade, F&& grow) {
    while (segment_ < blade.segment_count()) {
      const BladeModel::Segment& s = blade.segment(segment_);
      const double ax = resumed_ ? x_ : s.ax, ay = resumed_ ? y_ : s.ay;
      const bool last = segment_ + 1 == blade.segment_count();
      if ((ax != s.bx || ay != s.by) && !grow(ax, ay, s.bx, s.by)) return;
      x_ = s.bx, y_ = s.by;
      if (last) {
        resumed_ = true;
        return;
      }
      ++segment_, resumed_ = false;
    }
  }

 private:
  int segment_ = 0;
  double x_ = 0, y_ = 0;  // m, where the last segment was left
  bool resumed_ = false;
};

}  // namespace vsurg::haptics
