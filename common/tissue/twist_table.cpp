#include "common/tissue/twist_table.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "common/geometry/tet_embedding.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

Status CheckInputs(const TwistTableInputs& in) {
  const int n = static_cast<int>(in.mesh.positions.size());
  if (!(in.max_twist > 0 && in.max_twist <= std::numbers::pi))
    return InvalidArgument("max_twist", "must be within (0, π] rad");
  if (in.levels < 1 || in.levels > 32) return InvalidArgument("levels", "must be 1..32 per side");
  if (!in.origin.allFinite() || !in.axis.allFinite() || !(in.axis.norm() > 0))
    return InvalidArgument("axis", "the twist axis needs a finite point and a direction");
  if (in.face.empty() || in.fixed.empty())
    return InvalidArgument("face", "the twist needs a grasped face and fixed vertices");
  for (const std::vector<int>* list : {&in.face, &in.fixed})
    for (int v : *list)
      if (v < 0 || v >= n)
        return InvalidArgument("face", "vertex " + std::to_string(v) + " is not in the FEM mesh");
  return Status::Ok();
}

// The grasp's fraction of the way from the fixed end to the face, per FEM vertex (0..1): how
// much of a new increment of twist a first guess gives it.
std::vector<double> AxialShare(const TwistTableInputs& in, const Vec3& n) {
  auto mean_along = [&](const std::vector<int>& list) {
    double z = 0;
    for (int v : list) z += (in.mesh.positions[v] - in.origin).dot(n);
    return z / static_cast<double>(list.size());
  };
  const double z0 = mean_along(in.fixed), z1 = mean_along(in.face);
  std::vector<double> share;
  for (const Vec3& x : in.mesh.positions)
    share.push_back(z1 != z0 ? std::clamp(((x - in.origin).dot(n) - z0) / (z1 - z0), 0.0, 1.0)
                             : 1.0);
  return share;
}

// One increment from `x` (at twist `from`) to `to`: the guess, the held coordinates, Newton.
Expected<TwistedState> Increment(const TwistTableInputs& in, const std::vector<Vec3>& x,
                                 double from, double to) {
  const Vec3 n = in.axis.normalized();
  auto fem = HyperelasticFem::Create(in.mesh, in.material);
  if (!fem.ok()) return fem.error();
  const std::vector<double> share = AxialShare(in, n);
  auto turn = [&](const Vec3& p, double angle) {
    return Vec3(in.origin + Eigen::AngleAxisd(angle, n) * (p - in.origin));
  };
  std::vector<Vec3> guess(x.size());
  for (size_t v = 0; v < x.size(); ++v) guess[v] = turn(x[v], (to - from) * share[v]);
  fem->SetPositions(guess);
  for (int v : in.fixed)
    for (int a = 0; a < 3; ++a) fem->Hold(v, a, in.mesh.positions[v][a]);
  for (int v : in.face) {
    const Vec3 p = turn(in.mesh.positions[v], to);
    for (int a = 0; a < 3; ++a) fem->Hold(v, a, p[a]);
  }
  TwistedState s;
  s.twist = to;
  s.solve = fem->SolveStatic(60, 1e-9);
  if (!s.solve.converged)
    return Error{ErrorCode::kNumerical,
                 "the twist to " + std::to_string(to) + " rad did not converge (residual " +
                     std::to_string(s.solve.residual) + ")",
                 "fem"};
  s.positions = fem->positions();
  const Eigen::VectorXd f = fem->InternalForces();  // −∂E/∂x: the grasp exerts the opposite
  for (int v : in.face) {
    const Vec3 grasp = -f.segment<3>(3 * v);
    s.torque += (s.positions[v] - in.origin).cross(grasp).dot(n);
    s.axial += grasp.dot(n);
  }
  return s;
}

// From `x` at `from` to `to`, halving a step that does not converge (at most `depth` times).
Expected<TwistedState> Approach(const TwistTableInputs& in, const std::vector<Vec3>& x, double from,
                                double to, int depth, TwistTableReport* report) {
  auto s = Increment(in, x, from, to);
  if (report) ++report->increments;
  if (s.ok() || depth == 0) {
    if (s.ok() && report) {
      report->newton_iterations += s->solve.iterations;
      report->worst_residual = std::max(report->worst_residual, s->solve.residual);
    }
    return s;
  }
  const double mid = 0.5 * (from + to);
  auto half = Approach(in, x, from, mid, depth - 1, report);
  if (!half.ok()) return half.error();
  return Approach(in, half->positions, mid, to, depth - 1, report);
}

// A level's fields per display vertex (reduced.h's TwistTable), appended to the table.
void AppendLevel(const TwistTableInputs& in, const std::vector<geometry::EmbeddedPoint>& embedding,
                 const TwistedState& s, TwistTable& t) {
  const Vec3 n = in.axis.normalized();
  std::vector<Vec3> u(s.positions.size());
  for (size_t v = 0; v < u.size(); ++v) u[v] = s.positions[v] - in.mesh.positions[v];
  auto off_axis = [&](const Vec3& p) {
    const Vec3 r = p - in.origin;
    return Vec3(r - r.dot(n) * n);
  };
  for (size_t i = 0; i < in.display.size(); ++i) {
    const Vec3 d = geometry::Interpolate(embedding[i], u);
    const Vec3 r0 = off_axis(in.display[i]), r1 = off_axis(in.display[i] + d);
    t.warp.push_back(static_cast<float>(n.dot(d)));
    if (r0.squaredNorm() > 1e-12) {
      t.angle.push_back(static_cast<float>(std::atan2(n.dot(r0.cross(r1)), r0.dot(r1))));
      t.radial.push_back(static_cast<float>(r1.norm() / r0.norm() - 1));
      t.lateral.push_back(Vec3::Zero());
    } else {
      t.angle.push_back(0.f);
      t.radial.push_back(0.f);
      t.lateral.push_back(d - d.dot(n) * n);
    }
  }
  t.twist.push_back(s.twist);
  t.torque.push_back(s.torque);
  t.axial.push_back(s.axial);
}

}  // namespace

Expected<TwistedState> SolveTwisted(const TwistTableInputs& in, double twist,
                                    const TwistedState* from, int increments,
                                    TwistTableReport* report) {
  if (Status ok = CheckInputs(in); !ok.ok()) return ok.error();
  if (!std::isfinite(twist) || increments < 1)
    return InvalidArgument("twist", "needs a finite angle and at least one increment");
  TwistedState at;
  at.positions = from ? from->positions : in.mesh.positions;
  at.twist = from ? from->twist : 0.0;
  if (at.positions.size() != in.mesh.positions.size())
    return InvalidArgument("from", "the starting state is not of this mesh");
  if (twist == at.twist) {  // nothing to solve (at rest: no force to measure a residual by)
    at.solve.converged = true;
    return at;
  }
  const double start = at.twist;
  for (int k = 1; k <= increments; ++k) {
    auto next =
        Approach(in, at.positions, at.twist, start + (twist - start) * k / increments, 4, report);
    if (!next.ok()) return next.error();
    at = std::move(next).value();
  }
  return at;
}

void ContinuousAngles(TwistTable& t) {
  const size_t n = static_cast<size_t>(t.vertices);
  const int rest =
      static_cast<int>(std::find(t.twist.begin(), t.twist.end(), 0.0) - t.twist.begin());
  auto unwrap = [&](int level, int inner) {
    for (size_t i = 0; i < n; ++i) {
      const float a = t.angle[inner * n + i];
      float& b = t.angle[level * n + i];
      b = a + static_cast<float>(std::remainder(b - a, 2 * std::numbers::pi));
    }
  };
  for (int k = rest + 1; k < t.Levels(); ++k) unwrap(k, k - 1);
  for (int k = rest - 1; k >= 0; --k) unwrap(k, k + 1);
}

Expected<TwistTable> PrecomputeTwistTable(const TwistTableInputs& in, TwistTableReport* report) {
  if (Status ok = CheckInputs(in); !ok.ok()) return ok.error();
  auto embedding = geometry::EmbedPoints(in.mesh, in.display);
  if (!embedding.ok()) return embedding.error();
  // Each side solved outward from rest, level by level.
  std::vector<TwistedState> negative, positive;
  for (const double sign : {-1.0, 1.0}) {
    std::vector<TwistedState>& side = sign < 0 ? negative : positive;
    for (int k = 1; k <= in.levels; ++k) {
      auto s = SolveTwisted(in, sign * in.max_twist * k / in.levels,
                            side.empty() ? nullptr : &side.back(), 1, report);
      if (!s.ok()) return s.error();
      side.push_back(std::move(s).value());
    }
  }
  TwistTable t;
  t.origin = in.origin;
  t.axis = in.axis.normalized();
  t.vertices = static_cast<int>(in.display.size());
  for (auto it = negative.rbegin(); it != negative.rend(); ++it)
    AppendLevel(in, *embedding, *it, t);
  TwistedState rest;
  rest.positions = in.mesh.positions;
  AppendLevel(in, *embedding, rest, t);
  for (const TwistedState& s : positive) AppendLevel(in, *embedding, s, t);
  ContinuousAngles(t);
  for (const auto& e : *embedding) t.max_distance = std::max(t.max_distance, e.distance);
  if (Status ok = ValidateTwistTable(t, in.display.size()); !ok.ok())
    return Error{ErrorCode::kNumerical,
                 "the hyperelastic twist does not give a usable table: " + ok.error().message,
                 "fem"};
  return t;
}

Expected<TorqueRelaxation> TorqueRelaxation::Create(std::vector<PronyTerm> terms) {
  if (Status ok = CheckPronyTerms(terms); !ok.ok()) return ok.error();
  if (terms.size() > kMaxTerms)
    return InvalidArgument("relaxation", "at most " + std::to_string(kMaxTerms) + " terms");
  TorqueRelaxation r;
  r.terms_ = std::move(terms);
  r.h_.assign(r.terms_.size(), 0.0);
  return r;
}

TorqueRelaxation::Step TorqueRelaxation::Over(double dt) const {
  Step step;
  for (size_t i = 0; i < terms_.size(); ++i) {
    step.decay[i] = DecayOver(terms_[i], dt);
    step.scale += terms_[i].g * (step.decay[i].gamma - 1);
  }
  return step;
}

double TorqueRelaxation::Torque(double elastic, const Step& step) const {
  double torque = step.scale * elastic;
  for (size_t i = 0; i < terms_.size(); ++i)
    torque += step.decay[i].beta * h_[i] - terms_[i].g * step.decay[i].gamma * previous_;
  return torque;
}

void TorqueRelaxation::Commit(double elastic, const Step& step) {
  for (size_t i = 0; i < terms_.size(); ++i)
    h_[i] = step.decay[i].beta * h_[i] + terms_[i].g * step.decay[i].gamma * (elastic - previous_);
  previous_ = elastic;
}

void TorqueRelaxation::Reset() {
  std::fill(h_.begin(), h_.end(), 0.0);
  previous_ = 0;
}

double TorqueRelaxation::relaxed_share() const {
  double g = 1;
  for (const PronyTerm& t : terms_) g -= t.g;
  return g;
}

}  // namespace vsurg::tissue
