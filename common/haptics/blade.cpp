// BladeModel (blade.h): pressing until the puncture, then the crack drawn after the tip at the
// force its toughness sets.
#include "common/haptics/blade.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>

#include "common/core/require.h"

namespace vsurg::haptics {

Status CheckBlade(const BladeParams& p) {
  for (const auto& [field, v, unit] :
       {std::tuple{"toughness", p.toughness, "J/m²"}, std::tuple{"thickness", p.thickness, "m"},
        std::tuple{"width", p.width, "m"},
        std::tuple{"in_plane_stiffness", p.in_plane_stiffness, "N/m"},
        std::tuple{"normal_stiffness", p.normal_stiffness, "N/m"},
        std::tuple{"half_x", p.half_x, "m"}, std::tuple{"half_y", p.half_y, "m"},
        std::tuple{"min_segment", p.min_segment, "m"}}) {
    if (Status st = RequirePositive(field, v, unit); !st.ok()) return st;
  }
  if (!(p.angle >= 0 && p.angle < 1.3963))
    return InvalidArgument("angle", "angle: the edge's inclination must be in [0°, 80°)");
  return Status::Ok();
}

Expected<BladeModel> BladeModel::Create(const BladeParams& p) {
  if (Status st = CheckBlade(p); !st.ok()) return st.error();
  return BladeModel(p);
}

double BladeModel::PunctureForce() const {
  return std::sqrt(2 * p_.normal_stiffness * p_.toughness * p_.thickness * p_.width /
                   std::cos(p_.angle));
}

double BladeModel::CuttingForce() const {
  return p_.toughness * p_.thickness;
}

double BladeModel::Reach() const {
  return CuttingForce() / p_.in_plane_stiffness + 0.5 * p_.width;
}

BladeForce BladeModel::Step(const Vec3& tip) {
  if (!tip.allFinite()) return {};
  const bool over = std::abs(tip.x()) > p_.half_x || std::abs(tip.y()) > p_.half_y;
  if (tip.z() > 0 || over) {  // lifted out, or off the patch: free
    through_ = false;
    return {};
  }
  return through_ ? Draw(tip) : Press(tip);
}

// Below the surface, not through: the patch pushes back until the puncture; in its own slit, the
// blade goes straight through.
BladeForce BladeModel::Press(const Vec3& tip) {
  BladeForce out;
  double qx = 0, qy = 0;
  const bool in_slit = Nearest(tip.x(), tip.y(), qx, qy) >= 0 &&
                       std::hypot(tip.x() - qx, tip.y() - qy) <= 0.5 * p_.width;
  const double f = p_.normal_stiffness * -tip.z();
  if (!in_slit && f < PunctureForce()) {
    out.force = Vec3(0, 0, f);
    return out;
  }
  through_ = out.through = true;
  out.punctured = !in_slit;
  if (!in_slit) Grow(tip.x(), tip.y(), tip.x(), tip.y());  // the puncture: a crack of one point
  return out;
}

// Through: the tissue beside the crack resists the tip's distance from it; past the cutting force
// the crack follows the tip.
BladeForce BladeModel::Draw(const Vec3& tip) {
  BladeForce out;
  out.through = true;
  double qx = 0, qy = 0;
  const int seg = Nearest(tip.x(), tip.y(), qx, qy);
  if (seg < 0) return out;
  if (std::hypot(tip.x() - qx, tip.y() - qy) <= 0.5 * p_.width) {  // in a slit
    CutLigament(tip, seg, qx, qy);
    return out;
  }
  // A blade still at its front goes on from there; one pushed out of its slit elsewhere begins
  // from the nearest point of the cut (a branch).
  const Segment& last = segments_[count_ - 1];
  // (The front lags the crack by up to min_segment on a curve: a blade that far more is at it.)
  if (std::hypot(tip.x() - last.bx, tip.y() - last.by) <= Reach() + 2 * p_.min_segment)
    qx = last.bx, qy = last.by;
  const double dx = tip.x() - qx, dy = tip.y() - qy, dist = std::hypot(dx, dy);
  const double d = dist - 0.5 * p_.width;
  const double ux = dx / dist, uy = dy / dist;
  const double fc = CuttingForce(), k = p_.in_plane_stiffness;
  double f = k * d;
  if (f > fc) {  // the crack advances to where the tissue beside it holds exactly f_c
    const double grow = d - fc / k;
    if (count_ < kMaxSegments) {
      Grow(qx, qy, qx + grow * ux, qy + grow * uy);
      out.cutting = true, out.advance = grow;
      f = fc;
    }
  }
  out.force = Vec3(-f * ux, -f * uy, 0);
  return out;
}

// The blade reached another part of its cut (a circle closing on its start) while it was still
// loading its front: the ligament between the front and that part, shorter than the distance the
// tissue ahead of a front stretches before it gives (f_c / k_t), is cut through.
void BladeModel::CutLigament(const Vec3& tip, int seg, double qx, double qy) {
  if (count_ == 0 || seg == count_ - 1 || count_ >= kMaxSegments) return;
  const Segment& last = segments_[count_ - 1];
  if (std::hypot(tip.x() - last.bx, tip.y() - last.by) > Reach() + 2 * p_.min_segment) return;
  const double len = std::hypot(qx - last.bx, qy - last.by);
  if (len < p_.min_segment || len > Reach() + 0.5 * p_.width + 2 * p_.min_segment) return;
  segments_[count_++] = {last.bx, last.by, qx, qy};
  length_ += len;
}

int BladeModel::Nearest(double x, double y, double& qx, double& qy) const {
  double best = INFINITY;
  int at = -1;
  for (int i = 0; i < count_; ++i) {
    const Segment& s = segments_[i];
    const double ex = s.bx - s.ax, ey = s.by - s.ay, e2 = ex * ex + ey * ey;
    const double u = e2 > 0 ? std::clamp(((x - s.ax) * ex + (y - s.ay) * ey) / e2, 0.0, 1.0) : 0;
    const double px = s.ax + u * ex, py = s.ay + u * ey;
    const double d2 = (x - px) * (x - px) + (y - py) * (y - py);
    if (d2 < best) best = d2, qx = px, qy = py, at = i;
  }
  return at;
}

// The crack grown from (qx, qy) to (cx, cy): the last segment extended when this continues it in
// a straight line from its end, a new segment when it is at least min_segment long; a shorter
// step is left for the blade to take further (the force stays at f_c meanwhile).
void BladeModel::Grow(double qx, double qy, double cx, double cy) {
  const double len = std::hypot(cx - qx, cy - qy);
  if (count_ > 0) {
    Segment& last = segments_[count_ - 1];
    const double ex = last.bx - last.ax, ey = last.by - last.ay, el = std::hypot(ex, ey);
    const bool from_end = std::hypot(qx - last.bx, qy - last.by) < 1e-9;
    const bool straight =
        el > 0 && len > 0 && (ex * (cx - qx) + ey * (cy - qy)) / (el * len) > std::cos(0.02);
    if (from_end && (straight || el == 0)) {
      last.bx = cx, last.by = cy;
      length_ += len;
      return;
    }
  }
  if (count_ > 0 && len < p_.min_segment) return;
  if (count_ >= kMaxSegments) return;
  segments_[count_++] = {qx, qy, cx, cy};
  length_ += len;
}

}  // namespace vsurg::haptics
