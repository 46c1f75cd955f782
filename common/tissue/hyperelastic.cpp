#include "common/tissue/hyperelastic.h"

#include <Eigen/LU>
#include <Eigen/SparseCholesky>

#include <cmath>
#include <limits>
#include <string>

namespace vsurg::tissue {
namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;
constexpr double kInf = std::numeric_limits<double>::infinity();

// The edge matrix [x1 − x0, x2 − x0, x3 − x0].
Mat3 Edges(const std::array<int, 4>& v, const std::vector<Vec3>& x) {
  Mat3 d;
  for (int k = 0; k < 3; ++k) d.col(k) = x[v[k + 1]] - x[v[0]];
  return d;
}

// The material: μ, λ (Pa) and the stiffening b.
struct Law {
  double mu, lambda, b;
  // e^{b(I1−3)}: the isochoric part's stiffening factor (1 for neo-Hookean).
  double Factor(const Mat3& f) const {
    return b > 0 ? std::exp(b * ((f.transpose() * f).trace() - 3)) : 1.0;
  }
};

// ψ(F) per rest volume, Pa; +∞ for J ≤ 0.
double Density(const Mat3& f, const Law& m) {
  const double j = f.determinant();
  if (!(j > 0)) return kInf;
  const double ln_j = std::log(j);
  const double i1 = (f.transpose() * f).trace();
  const double isochoric =
      m.b > 0 ? m.mu / (2 * m.b) * std::expm1(m.b * (i1 - 3)) : 0.5 * m.mu * (i1 - 3);
  return isochoric - m.mu * ln_j + 0.5 * m.lambda * ln_j * ln_j;
}

// P(F) = μ·e·F − μ·F⁻ᵀ + λ·ln J·F⁻ᵀ.
Mat3 Stress(const Mat3& f, const Law& m) {
  const Mat3 f_inv_t = f.inverse().transpose();
  return m.mu * m.Factor(f) * f - m.mu * f_inv_t + m.lambda * std::log(f.determinant()) * f_inv_t;
}

// The element's nodal forces for a stress P: f_{1..3} = −V·P·Dm⁻ᵀ, f_0 = −Σ.
std::array<Vec3, 4> NodalForces(const Mat3& p, const Mat3& dm_inv, double volume) {
  const Mat3 h = -volume * p * dm_inv.transpose();
  return {-(h.col(0) + h.col(1) + h.col(2)), h.col(0), h.col(1), h.col(2)};
}

}  // namespace

Expected<HyperelasticFem> HyperelasticFem::Create(const geometry::TetMesh& rest,
                                                  HyperelasticParams p) {
  if (!(std::isfinite(p.young) && p.young > 0))
    return InvalidArgument("young", "Young's modulus must be finite and > 0 Pa");
  if (!(std::isfinite(p.poisson) && p.poisson > -1 && p.poisson < 0.5))
    return InvalidArgument("poisson", "Poisson's ratio must lie in (−1, 0.5)");
  if (!(std::isfinite(p.stiffening) && p.stiffening >= 0 && p.stiffening <= 100))
    return InvalidArgument("stiffening", "the exponential law's b must lie in [0, 100]");
  if (Status s = geometry::Validate(rest); !s.ok()) return s.error();
  HyperelasticFem m;
  m.mu_ = p.young / (2 * (1 + p.poisson));
  m.lambda_ = p.young * p.poisson / ((1 + p.poisson) * (1 - 2 * p.poisson));
  m.b_ = p.stiffening;
  m.x_ = rest.positions;
  m.f_ext_.assign(rest.positions.size(), Vec3::Zero());
  m.held_.assign(3 * rest.positions.size(), 0);
  for (int t = 0; t < rest.TetCount(); ++t) {
    const auto& tet = rest.tetrahedra[t];
    Element e{{tet[0], tet[1], tet[2], tet[3]}, Mat3::Zero(), 0};
    const Mat3 dm = Edges(e.v, rest.positions);
    e.volume = dm.determinant() / 6;
    if (!(e.volume > 1e-18))
      return InvalidArgument(
          "tetrahedra[" + std::to_string(t) + "]",
          "flat or inverted at rest (volume " + std::to_string(e.volume) + " m³)");
    e.dm_inv = dm.inverse();
    m.elements_.push_back(e);
  }
  return m;
}

void HyperelasticFem::Hold(int vertex, int axis, double value) {
  held_[3 * vertex + axis] = 1;
  x_[vertex][axis] = value;
}

void HyperelasticFem::SetExternalForce(int vertex, const Eigen::Vector3d& f) {
  f_ext_[vertex] = f;
}

void HyperelasticFem::SetPositions(const std::vector<Eigen::Vector3d>& x) {
  x_ = x;
}

Mat3 HyperelasticFem::Deformation(const Element& e, const std::vector<Vec3>& x) const {
  return Edges(e.v, x) * e.dm_inv;
}

double HyperelasticFem::StrainEnergy() const {
  double energy = 0;
  for (const Element& e : elements_)
    energy += e.volume * ElementDensity(&e - elements_.data(), Deformation(e, x_));
  return energy;
}

Eigen::VectorXd HyperelasticFem::InternalForces() const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(x_.size()));
  for (const Element& e : elements_) {
    const auto nodal =
        NodalForces(ElementStress(&e - elements_.data(), Deformation(e, x_)), e.dm_inv, e.volume);
    for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[a]) += nodal[a];
  }
  return f;
}

// Column (a, c) of the element's 12×12 tangent: the forces' change for a unit move of vertex a
// along axis c, negated (K = −∂f/∂x).
Eigen::SparseMatrix<double> HyperelasticFem::Tangent() const {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(elements_.size() * 144);
  for (const Element& e : elements_) {
    const Mat3 f = Deformation(e, x_);
    const Mat3 f_inv = f.inverse(), f_inv_t = f_inv.transpose();
    const double ln_j = std::log(f.determinant());
    const double factor = Law{mu_, lambda_, b_}.Factor(f);
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c) {
        Mat3 d_ds = Mat3::Zero();
        if (a == 0)
          d_ds.row(c).setConstant(-1);
        else
          d_ds(c, a - 1) = 1;
        const Mat3 df = d_ds * e.dm_inv;
        Mat3 dp = mu_ * factor * (df + 2 * b_ * (f.array() * df.array()).sum() * f) +
                  (mu_ - lambda_ * ln_j) * f_inv_t * df.transpose() * f_inv_t +
                  lambda_ * (f_inv * df).trace() * f_inv_t;
        if (!s_hist_.empty()) dp = scale_ * dp + df * s_hist_[&e - elements_.data()];
        const auto dforces = NodalForces(dp, e.dm_inv, e.volume);
        for (int b = 0; b < 4; ++b)
          for (int r = 0; r < 3; ++r)
            entries.emplace_back(3 * e.v[b] + r, 3 * e.v[a] + c, -dforces[b][r]);
      }
  }
  const auto n = 3 * static_cast<Eigen::Index>(x_.size());
  Eigen::SparseMatrix<double> k(n, n);
  k.setFromTriplets(entries.begin(), entries.end());
  return k;
}

double HyperelasticFem::ElementDensity(size_t e, const Mat3& f) const {
  const double psi = Density(f, {mu_, lambda_, b_});
  if (s_hist_.empty() || !std::isfinite(psi)) return psi;
  const Mat3 strain = f.transpose() * f - Mat3::Identity();
  return scale_ * psi + 0.5 * (s_hist_[e].array() * strain.array()).sum();
}

Mat3 HyperelasticFem::ElementStress(size_t e, const Mat3& f) const {
  const Mat3 p = Stress(f, {mu_, lambda_, b_});
  return s_hist_.empty() ? p : Mat3(scale_ * p + f * s_hist_[e]);
}

Status HyperelasticFem::SetRelaxation(std::vector<PronyTerm> terms) {
  double sum = 0;
  for (size_t i = 0; i < terms.size(); ++i) {
    const PronyTerm& t = terms[i];
    if (!(std::isfinite(t.g) && t.g >= 0 && std::isfinite(t.tau) && t.tau > 0))
      return InvalidArgument("relaxation[" + std::to_string(i) + "]",
                             "g must be >= 0 and tau > 0 s, both finite");
    sum += t.g;
  }
  if (!(sum < 1)) return InvalidArgument("relaxation", "the terms' g must sum to less than 1");
  prony_ = std::move(terms);
  const size_t n = elements_.size();
  s_hist_.assign(prony_.empty() ? 0 : n, Mat3::Zero());
  s_prev_.assign(prony_.empty() ? 0 : n, Mat3::Zero());
  h_.assign(n * prony_.size(), Mat3::Zero());
  scale_ = 1;
  for (size_t e = 0; e < s_prev_.size(); ++e) {  // the elastic stress of the present state
    const Mat3 f = Deformation(elements_[e], x_);
    s_prev_[e] = f.inverse() * Stress(f, {mu_, lambda_, b_});
  }
  return Status::Ok();
}

HyperelasticSolve HyperelasticFem::Step(double dt) {
  time_ += dt;
  if (prony_.empty()) return SolveStatic();
  const size_t terms = prony_.size();
  std::vector<double> beta(terms), gamma(terms);
  scale_ = 1;
  for (size_t i = 0; i < terms; ++i) {
    const double x = dt / prony_[i].tau;
    beta[i] = std::exp(-x);
    gamma[i] = x > 1e-12 ? -std::expm1(-x) / x : 1.0;
    scale_ += prony_[i].g * (gamma[i] - 1);  // g∞ + Σ g_i·γ_i, with g∞ = 1 − Σ g_i
  }
  for (size_t e = 0; e < elements_.size(); ++e) {
    s_hist_[e].setZero();
    for (size_t i = 0; i < terms; ++i)
      s_hist_[e] += beta[i] * h_[e * terms + i] - prony_[i].g * gamma[i] * s_prev_[e];
  }
  const HyperelasticSolve out = SolveStatic();
  for (size_t e = 0; e < elements_.size(); ++e) {
    const Mat3 f = Deformation(elements_[e], x_);
    const Mat3 s_e = f.inverse() * Stress(f, {mu_, lambda_, b_});
    for (size_t i = 0; i < terms; ++i)
      h_[e * terms + i] = beta[i] * h_[e * terms + i] + prony_[i].g * gamma[i] * (s_e - s_prev_[e]);
    s_prev_[e] = s_e;
  }
  return out;
}

double HyperelasticFem::Potential(const std::vector<Vec3>& x) const {
  double potential = 0;
  for (const Element& e : elements_) {
    const double psi = ElementDensity(&e - elements_.data(), Deformation(e, x));
    if (!std::isfinite(psi)) return kInf;
    potential += e.volume * psi;
  }
  for (size_t i = 0; i < x.size(); ++i) potential -= f_ext_[i].dot(x[i]);
  return potential;
}

Eigen::VectorXd HyperelasticFem::FreeResidual() const {
  Eigen::VectorXd r = InternalForces();
  for (size_t i = 0; i < x_.size(); ++i)
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) += f_ext_[i];
  for (Eigen::Index k = 0; k < r.size(); ++k)
    if (held_[k]) r[k] = 0;
  return r;
}

HyperelasticSolve HyperelasticFem::SolveStatic(int max_iterations, double tolerance) {
  HyperelasticSolve out;
  for (; out.iterations <= max_iterations; ++out.iterations) {
    // The residual against the largest force in play: the loads and the held coordinates'
    // reactions (a stretch by held coordinates alone has no load).
    const Eigen::VectorXd f = InternalForces();
    double scale = 1e-12;
    for (Eigen::Index k = 0; k < f.size(); ++k) {
      const double load = f_ext_[k / 3][k % 3];
      scale = std::max(scale, std::abs(held_[k] ? f[k] + load : load));
    }
    const Eigen::VectorXd r = FreeResidual();
    out.residual = r.lpNorm<Eigen::Infinity>() / scale;
    if (out.residual < tolerance) return out.converged = true, out;
    if (out.iterations == max_iterations) break;
    // Newton's direction on the free coordinates (held ones pinned by an identity row).
    Eigen::SparseMatrix<double> k = Tangent();
    for (int col = 0; col < k.outerSize(); ++col)
      for (Eigen::SparseMatrix<double>::InnerIterator it(k, col); it; ++it)
        if (held_[it.row()] || held_[it.col()]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(k);
    Eigen::VectorXd d = solver.info() == Eigen::Success ? solver.solve(r) : r;
    if (!(d.allFinite() && r.dot(d) > 0)) d = r;  // not a descent: the steepest one
    // Backtracking on the potential (Armijo), never into an inverted element.
    const double p0 = Potential(x_), slope = r.dot(d);
    bool accepted = false;
    for (double alpha = 1; alpha > 1e-12 && !accepted; alpha *= 0.5) {
      std::vector<Vec3> trial = x_;
      for (size_t i = 0; i < trial.size(); ++i)
        trial[i] += alpha * d.segment<3>(3 * static_cast<Eigen::Index>(i));
      const double p = Potential(trial);
      if (!std::isfinite(p)) continue;
      if (p <= p0 - 1e-4 * alpha * slope) {
        x_ = std::move(trial);
        accepted = true;
      } else if (alpha == 1 && std::abs(p - p0) <= 1e-12 * std::abs(p0)) {
        // At equilibrium the potential's change is below its rounding: the full Newton step is
        // judged by the residual instead.
        std::swap(x_, trial);
        if (FreeResidual().squaredNorm() < r.squaredNorm()) {
          accepted = true;
        } else {
          std::swap(x_, trial);
        }
      }
    }
    if (!accepted) break;
  }
  return out;
}

}  // namespace vsurg::tissue
