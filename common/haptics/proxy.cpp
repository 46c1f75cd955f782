#include "common/haptics/proxy.h"

#include <cmath>

namespace vsurg::haptics {
namespace {

// A degenerate face still needs a direction to push along; +z is as good as any.
Vec3 FaceNormal(const std::vector<geometry::Vec3>& x, const geometry::Triangle& t) {
  const Vec3 n = geometry::TriangleNormal(x, t);
  return n.isZero() ? Vec3(Vec3::UnitZ()) : n;
}

}  // namespace

Expected<ProxyContact> ProxyContact::Create(const ProxyParams& p) {
  auto non_negative = [](double v) { return std::isfinite(v) && v >= 0; };
  if (!non_negative(p.stiffness))
    return InvalidArgument("stiffness", "proxy stiffness must be ≥ 0 N/m");
  if (!non_negative(p.damping))
    return InvalidArgument("damping", "proxy damping must be ≥ 0 N·s/m");
  if (!non_negative(p.friction))
    return InvalidArgument("friction", "friction coefficient must be ≥ 0");
  if (!(std::isfinite(p.max_step) && p.max_step > 0))
    return InvalidArgument("max_step", "max proxy step must be > 0 m");
  if (!(p.min_normal_dot >= -1 && p.min_normal_dot <= 1)) {
    return InvalidArgument("min_normal_dot", "min normal dot must be in [-1, 1]");
  }
  return ProxyContact(p);
}

void ProxyContact::Reset() {
  state_ = ProxyState{};
  has_last_ = false;
  last_x_.setZero();
}

const ProxyState& ProxyContact::Update(const std::vector<geometry::Vec3>& x,
                                       const geometry::Bvh& bvh, const Vec3& hip, double dt,
                                       double surface_motion) {
  if (!hip.allFinite()) {  // the caller gates NaN already; stay safe regardless
    Reset();
    return state_;
  }
  const auto& tris = bvh.triangles();
  if (!state_.contact && has_last_) {
    const geometry::RayHit hit = bvh.FirstHit(x, last_hip_, hip);
    if (hit.triangle >= 0 && hit.front_face) {
      state_.contact = true;
      state_.scp = hit.point;
      state_.triangle = hit.triangle;
      state_.barycentric = hit.barycentric;
      state_.normal = FaceNormal(x, tris[hit.triangle]);
      last_x_ = state_.scp - hip;
    } else {
      // The surface may have moved over a resting tip (deforming tissue springing back): a tip
      // just under its closest face is inside. A tip beyond a thin sheet sees the sheet's near
      // face, whose normal points at it, so this never catches the far side.
      const geometry::ClosestHit c =
          free_faces_.Closest(bvh, x, surface_motion, hip, params_.max_step);
      if (c.triangle >= 0) {
        const Vec3 n = FaceNormal(x, tris[c.triangle]);
        if ((hip - c.point).dot(n) < 0) {
          state_.contact = true;
          state_.scp = c.point;
          state_.triangle = c.triangle;
          state_.barycentric = c.barycentric;
          state_.normal = n;
          last_x_ = state_.scp - hip;
        }
      }
    }
  } else if (state_.contact) {
    // Closest point to the tip among faces still facing the contact side, near the proxy.
    const double reach = (hip - state_.scp).norm() + params_.max_step;
    // The proxy's face starts each search: the tip rarely moves far from it in one update.
    geometry::ClosestHit c = contact_faces_.Closest(
        bvh, x, surface_motion, hip, reach, state_.normal, params_.min_normal_dot, state_.triangle);
    if (c.triangle < 0) {
      // Nothing acceptable in reach: hold the proxy on its face, re-evaluated on the new surface.
      c = bvh.Closest(x, state_.scp, params_.max_step, state_.normal, params_.min_normal_dot,
                      state_.triangle);
    }
    if (c.triangle >= 0) {
      Vec3 target = c.point;
      const Vec3 travel = target - state_.scp;
      if (travel.norm() > params_.max_step) {
        const geometry::ClosestHit s =
            bvh.Closest(x, state_.scp + travel * (params_.max_step / travel.norm()),
                        params_.max_step, state_.normal, params_.min_normal_dot, c.triangle);
        if (s.triangle >= 0) c = s;
        target = c.point;
      }
      const Vec3 n = FaceNormal(x, tris[c.triangle]);
      if ((hip - target).dot(n) >= 0) {
        state_.contact = false;  // the tip is back outside
      } else {
        bool stick = false;
        if (params_.friction > 0) {
          // Static friction: keep the old proxy while the force it gives stays in the cone.
          const Vec3 f_old = params_.stiffness * (state_.scp - hip);
          const double fn = f_old.dot(n);
          stick = fn > 0 && (f_old - fn * n).norm() <= params_.friction * fn;
        }
        if (!stick) {
          state_.scp = target;
          state_.triangle = c.triangle;
          state_.barycentric = c.barycentric;
        }
        state_.normal = n;
      }
    } else {
      state_.contact = false;
    }
  }
  if (state_.contact) {
    const Vec3 xv = state_.scp - hip;
    const Vec3 xdot = dt > 0 && std::isfinite(dt) ? Vec3((xv - last_x_) / dt) : Vec3::Zero();
    state_.penetration = xv.dot(state_.normal);
    state_.force = params_.stiffness * xv + params_.damping * xdot;  // the mass-spring paper §2.3
    state_.jacobian = -params_.stiffness * state_.normal * state_.normal.transpose();
    last_x_ = xv;
  } else {
    state_.scp = hip;
    state_.triangle = -1;
    state_.penetration = 0;
    state_.force.setZero();
    state_.jacobian.setZero();
    last_x_.setZero();
  }
  last_hip_ = hip;
  has_last_ = true;
  return state_;
}

}  // namespace vsurg::haptics
