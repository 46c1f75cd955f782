#include "common/tissue/membrane_fem.h"

#include <algorithm>
#include <cmath>
#include <iostream>  // Eigen/MetisSupport uses std::cerr
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/MetisSupport>
#include <Eigen/SparseCholesky>

#include "common/tissue/cut_membrane.h"

namespace vsurg::tissue {
namespace {

using geometry::Vec3;
using Mat32 = Eigen::Matrix<double, 3, 2>;

bool Finite(double v) {
  return std::isfinite(v);
}

// F = Ds·Dm⁻¹ of the triangle with corners `v` at `x`.
Mat32 DeformationGradient(const std::array<int32_t, 3>& v, const Eigen::Matrix2d& dm_inv,
                          const std::vector<Vec3>& x) {
  Mat32 ds;
  ds.col(0) = x[v[1]] - x[v[0]];
  ds.col(1) = x[v[2]] - x[v[0]];
  return ds * dm_inv;
}

Eigen::Matrix2d GreenStrain(const Mat32& f) {
  return 0.5 * (f.transpose() * f - Eigen::Matrix2d::Identity());
}

// S = λ*·tr(E)·I + 2μ·E; linear, so it also maps a strain's change dE to the stress's dS.
Eigen::Matrix2d Stress(double lambda, double mu, const Eigen::Matrix2d& strain) {
  return lambda * strain.trace() * Eigen::Matrix2d::Identity() + 2 * mu * strain;
}

}  // namespace

Status CheckMembraneFem(const MembraneFemParams& p) {
  if (!(Finite(p.thickness) && p.thickness > 0))
    return InvalidArgument("thickness", "thickness: must be > 0 m");
  if (!(Finite(p.youngs_modulus) && p.youngs_modulus > 0))
    return InvalidArgument("youngs_modulus", "youngs_modulus: must be > 0 Pa");
  if (!(p.poisson_ratio >= 0 && p.poisson_ratio < 0.5))
    return InvalidArgument("poisson_ratio", "poisson_ratio: must be in [0, 0.5)");
  if (!(p.pretension >= 0 && p.pretension < 0.5))
    return InvalidArgument("pretension", "pretension: must be in [0, 0.5)");
  return Status::Ok();
}

MembraneMesh MeshOf(const CutMembrane& patch) {
  MembraneMesh m;
  const int n = static_cast<int>(patch.positions().size());
  for (int i = 0; i < n; ++i) {
    m.rest.push_back(patch.Rest(i));
    m.fixed.push_back(patch.OnFrame(i));
  }
  for (int f = 0; f < patch.FaceCount(); ++f)
    if (!patch.Removed(f)) m.faces.push_back(patch.face(f).v);
  return m;
}

Expected<MembraneFem> MembraneFem::Create(const MembraneMesh& mesh, const MembraneFemParams& p) {
  if (Status s = CheckMembraneFem(p); !s.ok()) return s.error();
  const int n = static_cast<int>(mesh.rest.size());
  if (mesh.fixed.size() != mesh.rest.size())
    return InvalidArgument("fixed", "fixed: one flag per vertex");
  MembraneFem m;
  m.p_ = p;
  const double nu = p.poisson_ratio;
  m.lambda_ = p.youngs_modulus * nu / (1 - nu * nu);
  m.mu_ = p.youngs_modulus / (2 * (1 + nu));
  const double shrink = 1 - p.pretension;
  for (const auto& f : mesh.faces) {
    for (int32_t v : f)
      if (v < 0 || v >= n) return InvalidArgument("faces", "faces: a vertex out of range");
    Eigen::Matrix2d dm;
    dm.col(0) = shrink * (mesh.rest[f[1]] - mesh.rest[f[0]]);
    dm.col(1) = shrink * (mesh.rest[f[2]] - mesh.rest[f[0]]);
    const double area = 0.5 * dm.determinant();
    if (!(area > 0)) return InvalidArgument("faces", "faces: each counter-clockwise, area > 0");
    m.elements_.push_back({f, dm.inverse(), p.thickness * area});
  }
  for (const Eigen::Vector2d& r : mesh.rest) m.x_.emplace_back(r.x(), r.y(), 0.0);
  m.load_.assign(n, Vec3::Zero());
  // A vertex no face uses (a copy a cut made and left, a freed piece's) carries nothing: held.
  m.fixed_ = mesh.fixed;
  std::vector<bool> used(n, false);
  for (const auto& f : mesh.faces)
    for (int32_t v : f) used[v] = true;
  for (int i = 0; i < n; ++i) m.fixed_[i] = m.fixed_[i] || !used[i];
  int free = 0;
  for (int i = 0; i < n; ++i) m.dof_.push_back(m.fixed_[i] ? -1 : 3 * free++);
  return m;
}

void MembraneFem::SetLoad(int vertex, const Vec3& force) {
  if (vertex >= 0 && vertex < VertexCount()) load_[vertex] = force;
}

void MembraneFem::Hold(int vertex, const Vec3& target, double stiffness) {
  held_ = vertex >= 0 && vertex < VertexCount() ? vertex : -1;
  hold_target_ = target;
  hold_k_ = stiffness;
}

void MembraneFem::Release() {
  held_ = -1;
}

double MembraneFem::Tension() const {
  const double s = 1 / (1 - p_.pretension);
  return p_.thickness * (lambda_ + mu_) * (s * s - 1);
}

double MembraneFem::ElementEnergy(const Element& e, const std::vector<Vec3>& x) const {
  const Eigen::Matrix2d strain = GreenStrain(DeformationGradient(e.v, e.dm_inv, x));
  const double tr = strain.trace();
  return e.volume * (mu_ * strain.squaredNorm() + 0.5 * lambda_ * tr * tr);
}

Eigen::Matrix3d MembraneFem::ElementGradient(const Element& e) const {
  const Mat32 f = DeformationGradient(e.v, e.dm_inv, x_);
  const Eigen::Matrix2d s = Stress(lambda_, mu_, GreenStrain(f));
  const Mat32 h = e.volume * f * s * e.dm_inv.transpose();  // ∂W/∂Ds
  Eigen::Matrix3d g;
  g.col(1) = h.col(0);
  g.col(2) = h.col(1);
  g.col(0) = -h.col(0) - h.col(1);
  return g;
}

// Column (3a + c) is the change of every ∂W/∂x_k for a unit move of vertex a along axis c:
// dDs, dF = dDs·Dm⁻¹, dE = ½(dFᵀF + FᵀdF), dS = λ*·tr(dE)·I + 2μ·dE, dP = dF·S + F·dS.
Eigen::Matrix<double, 9, 9> MembraneFem::ElementHessian(const Element& e) const {
  const Mat32 f = DeformationGradient(e.v, e.dm_inv, x_);
  const Eigen::Matrix2d s = Stress(lambda_, mu_, GreenStrain(f));
  Eigen::Matrix<double, 9, 9> k;
  for (int a = 0; a < 3; ++a) {
    for (int c = 0; c < 3; ++c) {
      Mat32 dds = Mat32::Zero();
      if (a == 0) dds.row(c) << -1, -1;
      if (a > 0) dds(c, a - 1) = 1;
      const Mat32 df = dds * e.dm_inv;
      const Eigen::Matrix2d de = 0.5 * (df.transpose() * f + f.transpose() * df);
      const Eigen::Matrix2d dse = Stress(lambda_, mu_, de);
      const Mat32 dh = e.volume * (df * s + f * dse) * e.dm_inv.transpose();
      k.block<3, 1>(3, 3 * a + c) = dh.col(0);
      k.block<3, 1>(6, 3 * a + c) = dh.col(1);
      k.block<3, 1>(0, 3 * a + c) = -dh.col(0) - dh.col(1);
    }
  }
  // The positive part: a compressed triangle adds no negative stiffness (see the header).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(0.5 * (k + k.transpose()));
  const auto values = eig.eigenvalues().cwiseMax(0.0);
  return eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
}

double MembraneFem::EnergyAt(const std::vector<Vec3>& x) const {
  double w = 0;
  for (const Element& e : elements_) w += ElementEnergy(e, x);
  for (size_t i = 0; i < x.size(); ++i) w -= load_[i].dot(x[i]);
  if (held_ >= 0) w += 0.5 * hold_k_ * (x[held_] - hold_target_).squaredNorm();
  return w;
}

double MembraneFem::Energy() const {
  return EnergyAt(x_);
}

std::vector<Vec3> MembraneFem::Forces() const {
  std::vector<Vec3> f = load_;
  for (const Element& e : elements_) {
    const Eigen::Matrix3d g = ElementGradient(e);
    for (int k = 0; k < 3; ++k) f[e.v[k]] -= g.col(k);
  }
  if (held_ >= 0) f[held_] -= hold_k_ * (x_[held_] - hold_target_);
  for (size_t i = 0; i < f.size(); ++i)
    if (fixed_[i]) f[i].setZero();
  return f;
}

Expected<double> MembraneFem::NewtonStep() {
  const int n = VertexCount();
  const int unknowns = static_cast<int>(std::count(fixed_.begin(), fixed_.end(), false)) * 3;
  const std::vector<Vec3> force = Forces();
  double residual = 0;
  Eigen::VectorXd rhs(unknowns);
  for (int i = 0; i < n; ++i) {
    if (dof_[i] < 0) continue;
    rhs.segment<3>(dof_[i]) = force[i];
    residual = std::max(residual, force[i].norm());
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(elements_.size() * 45 + 3);
  for (const Element& e : elements_) {
    const Eigen::Matrix<double, 9, 9> k = ElementHessian(e);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const int ra = dof_[e.v[a]], cb = dof_[e.v[b]];
        if (ra < 0 || cb < 0 || cb > ra) continue;  // the lower triangle
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            if (ra + i >= cb + j) triplets.emplace_back(ra + i, cb + j, k(3 * a + i, 3 * b + j));
      }
  }
  if (held_ >= 0 && dof_[held_] >= 0)
    for (int i = 0; i < 3; ++i) triplets.emplace_back(dof_[held_] + i, dof_[held_] + i, hold_k_);
  Eigen::SparseMatrix<double> kt(unknowns, unknowns);
  kt.setFromTriplets(triplets.begin(), triplets.end());
  // A vertex whose every triangle is slack (a corner a cut left on one triangle, folded) has no
  // stiffness in some direction: the tangent is then shifted by a small multiple of its mean
  // diagonal, growing until it factors (a damped Newton step; the search below keeps it downhill).
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::MetisOrdering<int>> ldlt;
  ldlt.analyzePattern(kt);
  const double mean = kt.diagonal().sum() / std::max(1, unknowns);
  Eigen::SparseMatrix<double> shift(unknowns, unknowns);
  shift.setIdentity();
  for (double lm = 0;; lm = lm == 0 ? 1e-9 : 100 * lm) {
    ldlt.factorize(lm == 0 ? kt : Eigen::SparseMatrix<double>(kt + lm * mean * shift));
    if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 0) break;
    if (lm > 1e-2)
      return Error{ErrorCode::kNumerical, "membrane: the tangent is singular (a loose vertex)", ""};
  }
  const Eigen::VectorXd dx = ldlt.solve(rhs);
  // Armijo on the energy along the step (a descent direction: the tangent is positive definite).
  const double w0 = Energy(), slope = -rhs.dot(dx);
  std::vector<Vec3> trial = x_;
  // Near the answer the decrease falls below the energy's rounding: the full step is taken.
  const bool resolvable = -slope > 1e-12 * std::abs(w0);
  for (double step = 1; step > 1e-8; step *= 0.5) {
    for (int i = 0; i < n; ++i)
      if (dof_[i] >= 0) trial[i] = x_[i] + step * dx.segment<3>(dof_[i]);
    if (!resolvable || EnergyAt(trial) <= w0 + 1e-4 * step * slope) break;
  }
  last_move_ = 0;
  for (int i = 0; i < n; ++i) last_move_ = std::max(last_move_, (trial[i] - x_[i]).norm());
  x_ = trial;
  return residual;
}

Expected<MembraneFem::Solve> MembraneFem::SolveStatic(double tolerance, int max_iterations,
                                                      double move_tolerance) {
  Solve out;
  for (;;) {
    std::vector<Vec3> f = Forces();
    out.residual = 0;
    for (const Vec3& v : f) out.residual = std::max(out.residual, v.norm());
    out.last_move = out.iterations > 0 ? last_move_ : 0;
    if (out.residual <= tolerance || (out.iterations > 0 && last_move_ <= move_tolerance)) {
      out.converged = true;
      return out;
    }
    if (out.iterations >= max_iterations) return out;
    auto step = NewtonStep();
    if (!step.ok()) return step.error();
    ++out.iterations;
  }
}

}  // namespace vsurg::tissue
