// The reduced twist model at run time (common/tissue/reduced.h, 1.): a table of load levels, a
// linear field being the table of three, evaluated as a few multiply-adds per display vertex.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "common/tissue/reduced.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

// Two unit vectors completing `axis` to a right-handed frame.
void Frame(const Vec3& axis, Vec3& e1, Vec3& e2) {
  const Vec3 helper = std::abs(axis.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  e1 = axis.cross(helper).normalized();
  e2 = axis.cross(e1);
}

// sin φ and cos φ − 1 for |φ| ≤ π, by the half angle: Taylor series of ψ = φ/2 (|ψ| ≤ π/2,
// errors < 4e-6 to ψ⁹ and ψ¹⁰), then sin φ = 2·sin ψ·cos ψ, cos φ − 1 = −2·sin²ψ (no cancellation
// at small angles, where the displacement is small too). Branch-free float arithmetic, so the
// per-vertex loop vectorises (std::sin/cos per vertex would cost about 20× more: the rejected
// axis–angle variant of coil_deformation.h).
struct SinCos {
  float sin, cos_minus_1;
};
inline SinCos SinCosM1(float phi) {
  const float x = 0.5f * phi, x2 = x * x;
  const float s =
      x * (1.f + x2 * (-1.f / 6 + x2 * (1.f / 120 + x2 * (-1.f / 5040 + x2 * (1.f / 362880)))));
  const float c =
      1.f + x2 * (-1.f / 2 +
                  x2 * (1.f / 24 + x2 * (-1.f / 720 + x2 * (1.f / 40320 + x2 * (-1.f / 3628800)))));
  return {2.f * s * c, -2.f * s * s};
}

// One level's fields (pointers into the model's level-major arrays).
struct LevelFields {
  const float* __restrict a;
  const float* __restrict w;
  const float* __restrict q;
  const float* __restrict l1;
  const float* __restrict l2;
};

// The twist's displacement in the axis frame, vertex by vertex, for the fields t0·(level 0) +
// t1·(level 1) (restrict parameters: GCC vectorises this only when it knows the arrays do not
// overlap). Built twice, for AVX2 (8 floats a step) and the x86-64 baseline (SSE2, 4), the loader
// picking the one the CPU runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
void TwistDisplacements(int nv, float t0, float t1, LevelFields f0, LevelFields f1,
                        const float* __restrict r1, const float* __restrict r2,
                        const float (&basis)[9], float* __restrict ox, float* __restrict oy,
                        float* __restrict oz) {
  for (int i = 0; i < nv; ++i) {
    const SinCos sc = SinCosM1(t0 * f0.a[i] + t1 * f1.a[i]);
    const float s = sc.sin, cm1 = sc.cos_minus_1;
    // The radial strain held within ±50% so a torque far past the table cannot pull a vertex
    // through the axis. (clamp(x, −½, ½) = ½·(|x + ½| − |x − ½|): no branch, so the loop still
    // vectorises.)
    const float tq = t0 * f0.q[i] + t1 * f1.q[i];
    const float grow = 1.f + 0.5f * (std::fabs(tq + 0.5f) - std::fabs(tq - 0.5f));
    const float diag = (grow - 1.f) + grow * cm1;  // grow·cos φ − 1
    const float dx = diag * r1[i] - grow * s * r2[i] + t0 * f0.l1[i] + t1 * f1.l1[i];
    const float dy = grow * s * r1[i] + diag * r2[i] + t0 * f0.l2[i] + t1 * f1.l2[i];
    const float dz = t0 * f0.w[i] + t1 * f1.w[i];
    ox[i] = basis[0] * dx + basis[3] * dy + basis[6] * dz;  // into the world frame
    oy[i] = basis[1] * dx + basis[4] * dy + basis[7] * dz;
    oz[i] = basis[2] * dx + basis[5] * dy + basis[8] * dz;
  }
}

// Linear interpolation of a piecewise-linear curve through (xs, ys) on segment k, extended past
// its ends.
double Along(const std::vector<double>& xs, const std::vector<double>& ys, int k, double x) {
  return ys[k] + (x - xs[k]) * (ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k]);
}

}  // namespace

TwistTable LinearTwistTable(const TwistField& field) {
  TwistTable t;
  t.origin = field.origin;
  t.axis = field.axis;
  t.twist = {-field.grasp_compliance, 0.0, field.grasp_compliance};
  t.torque = {-1.0, 0.0, 1.0};
  t.axial = {0.0, 0.0, 0.0};
  const size_t n = field.angle.size();
  t.vertices = static_cast<int>(n);
  for (const double sign : {-1.0, 0.0, 1.0}) {
    const float f = static_cast<float>(sign);
    for (size_t i = 0; i < n; ++i) {
      t.angle.push_back(f * field.angle[i]);
      t.warp.push_back(f * field.warp[i]);
      t.radial.push_back(f * field.radial[i]);
      t.lateral.push_back(sign * (i < field.lateral.size() ? field.lateral[i] : Vec3::Zero()));
    }
  }
  t.max_distance = field.max_distance;
  return t;
}

Status ValidateTwistTable(const TwistTable& t, size_t display_vertices) {
  const size_t levels = t.twist.size(), n = display_vertices;
  if (levels < 2 || t.torque.size() != levels || t.axial.size() != levels ||
      t.vertices != static_cast<int>(n) || t.angle.size() != levels * n ||
      t.warp.size() != levels * n || t.radial.size() != levels * n ||
      t.lateral.size() != levels * n)
    return InvalidArgument("table", "the twist table does not match the surface (" +
                                        std::to_string(t.vertices) + " against " +
                                        std::to_string(n) + " vertices, " + std::to_string(levels) +
                                        " levels)");
  if (!t.origin.allFinite() || !t.axis.allFinite() || std::abs(t.axis.norm() - 1) > 1e-6)
    return InvalidArgument("table", "the twist axis is not a finite unit vector");
  bool rest = false;
  for (size_t k = 0; k < levels; ++k) {
    if (!std::isfinite(t.twist[k]) || !std::isfinite(t.torque[k]) || !std::isfinite(t.axial[k]))
      return InvalidArgument("table", "level " + std::to_string(k) + " is not finite");
    if (k > 0 && !(t.twist[k] > t.twist[k - 1] && t.torque[k] > t.torque[k - 1]))
      return InvalidArgument(
          "table", "the levels' twist and torque must rise (level " + std::to_string(k) + ")");
    rest = rest || (t.twist[k] == 0 && t.torque[k] == 0);
  }
  if (!rest) return InvalidArgument("table", "no level at rest (0 rad, 0 N·m)");
  for (const std::vector<float>* values : {&t.angle, &t.warp, &t.radial})
    for (float x : *values)
      if (!std::isfinite(x)) return InvalidArgument("table", "the fields are not finite");
  for (const Vec3& l : t.lateral)
    if (!l.allFinite()) return InvalidArgument("table", "the fields are not finite");
  return Status::Ok();
}

Expected<ReducedTwistModel> ReducedTwistModel::Create(const TwistField& field,
                                                      const std::vector<Vec3>& display_rest,
                                                      double max_twist) {
  const size_t nv = display_rest.size();
  if (field.angle.size() != nv || field.warp.size() != nv || field.radial.size() != nv ||
      field.lateral.size() != nv)
    return InvalidArgument("field", "the twist field has " + std::to_string(field.angle.size()) +
                                        " vertices, the surface " + std::to_string(nv));
  if (!(field.grasp_compliance > 0) || !std::isfinite(field.grasp_compliance))
    return InvalidArgument("field", "the grasp compliance must be > 0");
  if (!field.axis.allFinite() || !(field.axis.norm() > 0) || !field.origin.allFinite())
    return InvalidArgument("field", "the twist axis is not finite");
  TwistField unit = field;
  unit.axis = field.axis.normalized();
  return Create(LinearTwistTable(unit), display_rest, max_twist);
}

Expected<ReducedTwistModel> ReducedTwistModel::Create(const TwistTable& table,
                                                      const std::vector<Vec3>& display_rest,
                                                      double max_twist) {
  const size_t nv = display_rest.size();
  if (!(max_twist > 0 && max_twist <= std::numbers::pi))
    return InvalidArgument("max_twist", "must be within (0, π] rad");
  if (Status ok = ValidateTwistTable(table, nv); !ok.ok()) return ok.error();
  ReducedTwistModel m;
  m.origin_ = table.origin;
  m.axis_ = table.axis.normalized();
  Frame(m.axis_, m.e1_, m.e2_);
  m.nv_ = static_cast<int>(nv);
  for (size_t i = 0; i < nv; ++i) {
    if (!display_rest[i].allFinite())
      return InvalidArgument("display", "vertex " + std::to_string(i) + " is not finite");
    const Vec3 d = display_rest[i] - m.origin_;
    m.r1_.push_back(static_cast<float>(d.dot(m.e1_)));
    m.r2_.push_back(static_cast<float>(d.dot(m.e2_)));
  }
  const int levels = table.Levels();
  std::vector<double> most(levels, 0.0);  // each level's largest vertex angle, rad
  for (int k = 0; k < levels; ++k)
    for (size_t i = 0; i < nv; ++i) {
      const size_t at = k * nv + i;
      m.angle_.push_back(table.angle[at]);
      m.warp_.push_back(table.warp[at]);
      m.radial_.push_back(table.radial[at]);
      m.l1_.push_back(static_cast<float>(table.lateral[at].dot(m.e1_)));
      m.l2_.push_back(static_cast<float>(table.lateral[at].dot(m.e2_)));
      most[k] = std::max(most[k], std::abs(static_cast<double>(table.angle[at])));
    }
  m.level_twist_ = table.twist;
  m.level_torque_ = table.torque;
  m.rest_level_ = static_cast<int>(std::find(table.twist.begin(), table.twist.end(), 0.0) -
                                   table.twist.begin());
  // Each side's capacity: walking out from rest, the torque at which the largest vertex angle
  // reaches max_twist, along the last segment extended when no level does.
  auto side = [&](int step) {
    for (int k = m.rest_level_ + step;; k += step) {
      const int j = k - step;
      const bool last = k + step < 0 || k + step >= levels;
      if (most[k] >= max_twist || last) {
        if (!(most[k] > most[j])) return std::abs(table.torque[k]);
        const double s = (max_twist - most[j]) / (most[k] - most[j]);
        return std::abs(table.torque[j] + s * (table.torque[k] - table.torque[j]));
      }
    }
  };
  m.capacity_lo_ = m.rest_level_ > 0 ? side(-1) : 0.0;
  m.capacity_hi_ = m.rest_level_ + 1 < levels ? side(+1) : 0.0;
  m.rest_ = display_rest;
  m.positions_ = display_rest;
  m.dx_.assign(nv, 0.f);
  m.dy_.assign(nv, 0.f);
  m.dz_.assign(nv, 0.f);
  return m;
}

int ReducedTwistModel::Segment(const std::vector<double>& curve, double x) const {
  const int last = static_cast<int>(curve.size()) - 2;
  int k = 0;
  while (k < last && x > curve[k + 1]) ++k;
  return k;
}

double ReducedTwistModel::grasp_stiffness() const {
  const int k = std::min(rest_level_, Levels() - 2);
  return (level_torque_[k + 1] - level_torque_[k]) / (level_twist_[k + 1] - level_twist_[k]);
}

double ReducedTwistModel::grasp_twist(double torque) const {
  return Along(level_torque_, level_twist_, Segment(level_torque_, torque), torque);
}

ReducedTwistModel::Answer ReducedTwistModel::TorqueAt(double twist) const {
  Answer a;
  if (!std::isfinite(twist)) return a;
  const int k = Segment(level_twist_, twist);
  a.torque = Along(level_twist_, level_torque_, k, twist);
  a.stiffness = (level_torque_[k + 1] - level_torque_[k]) / (level_twist_[k + 1] - level_twist_[k]);
  if (a.torque > capacity_hi_ || a.torque < -capacity_lo_) {
    a.torque = std::clamp(a.torque, -capacity_lo_, capacity_hi_);
    a.stiffness = 0;
    a.overload = true;
  }
  return a;
}

ReducedStats ReducedTwistModel::Update(double torque) {
  ReducedStats stats;
  if (!std::isfinite(torque)) {
    stats.ok = false;
    return stats;
  }
  if (torque > capacity_hi_ || torque < -capacity_lo_) {
    torque = std::clamp(torque, -capacity_lo_, capacity_hi_);
    stats.saturated = true;
  }
  stats.load = torque;
  // The segment holding the torque and the two levels' weights; a segment from rest weighs the
  // rest level (all zero) by 0 and reads the other level twice, so a linear field costs what
  // one level does.
  const int k = Segment(level_torque_, torque);
  const double s = (torque - level_torque_[k]) / (level_torque_[k + 1] - level_torque_[k]);
  auto fields = [&](int level) {
    const size_t at = static_cast<size_t>(level) * nv_;
    return LevelFields{angle_.data() + at, warp_.data() + at, radial_.data() + at, l1_.data() + at,
                       l2_.data() + at};
  };
  float t0 = static_cast<float>(1 - s), t1 = static_cast<float>(s);
  LevelFields f0 = fields(k), f1 = fields(k + 1);
  if (k == rest_level_) f0 = f1, t0 = 0;
  if (k + 1 == rest_level_) f1 = f0, t1 = 0;
  float basis[9];
  for (int d = 0; d < 3; ++d) {
    basis[d] = static_cast<float>(e1_[d]);
    basis[3 + d] = static_cast<float>(e2_[d]);
    basis[6 + d] = static_cast<float>(axis_[d]);
  }
  // Displacements in float (relative precision of the displacement itself), structure of
  // arrays so the loop vectorises; then added to the rest positions in double.
  float* __restrict ox = dx_.data();
  float* __restrict oy = dy_.data();
  float* __restrict oz = dz_.data();
  TwistDisplacements(nv_, t0, t1, f0, f1, r1_.data(), r2_.data(), basis, ox, oy, oz);
  const double* __restrict rest = rest_.data()->data();  // Vec3 is 3 packed doubles
  double* __restrict out = positions_.data()->data();
  for (int i = 0; i < nv_; ++i) {
    out[3 * i + 0] = rest[3 * i + 0] + ox[i];
    out[3 * i + 1] = rest[3 * i + 1] + oy[i];
    out[3 * i + 2] = rest[3 * i + 2] + oz[i];
  }
  return stats;
}

}  // namespace vsurg::tissue
