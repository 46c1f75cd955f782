#include "common/tissue/hyperelastic.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <iostream>  // Eigen's METIS bridge writes to std::cerr without including it itself
#include <limits>
#include <string>

#include <Eigen/MetisSupport>

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

// The law's volumetric terms g(J) = −a·ln J + (c/2)·(ln J)² (a = μ, c = λ per element; a = 0,
// c = λ at the vertices), continued below kInvertedJ by their second-order Taylor expansion
// there: finite for a flat or inverted element (J ≤ 0), C² at the join, and falling as J rises
// (g' < 0 below it), so an inverted element is pushed back towards positive volume.
struct LogTerms {
  static constexpr double kInvertedJ = 0.1;
  double a, c;
  double Value(double j) const {
    if (j >= kInvertedJ) {
      const double l = std::log(j);
      return -a * l + 0.5 * c * l * l;
    }
    const double d = j - kInvertedJ;
    return Value(kInvertedJ) + First(kInvertedJ) * d + 0.5 * Second(kInvertedJ) * d * d;
  }
  double First(double j) const {  // g'(J), Pa
    if (j >= kInvertedJ) return (-a + c * std::log(j)) / j;
    return First(kInvertedJ) + Second(kInvertedJ) * (j - kInvertedJ);
  }
  double Second(double j) const {  // g''(J), Pa
    const double at = std::max(j, kInvertedJ);
    return (a + c * (1 - std::log(at))) / (at * at);
  }
};

// cof F = ∂J/∂F = J·F⁻ᵀ, defined for every F: its columns are f₂ × f₃, f₃ × f₁, f₁ × f₂.
Mat3 Cofactor(const Mat3& f) {
  Mat3 c;
  c << f.col(1).cross(f.col(2)), f.col(2).cross(f.col(0)), f.col(0).cross(f.col(1));
  return c;
}
// Its change along dF.
Mat3 CofactorChange(const Mat3& f, const Mat3& df) {
  Mat3 c;
  c << df.col(1).cross(f.col(2)) + f.col(1).cross(df.col(2)),
      df.col(2).cross(f.col(0)) + f.col(2).cross(df.col(0)),
      df.col(0).cross(f.col(1)) + f.col(0).cross(df.col(1));
  return c;
}

// ψ(F) per rest volume, Pa: the isochoric part and g(J).
double Density(const Mat3& f, const Law& m) {
  const double i1 = (f.transpose() * f).trace();
  const double isochoric =
      m.b > 0 ? m.mu / (2 * m.b) * std::expm1(m.b * (i1 - 3)) : 0.5 * m.mu * (i1 - 3);
  return isochoric + LogTerms{m.mu, m.lambda}.Value(f.determinant());
}

// P(F) = μ·e·F + g'(J)·cof F (= μ·e·F − μ·F⁻ᵀ + λ·ln J·F⁻ᵀ for J ≥ kInvertedJ).
Mat3 Stress(const Mat3& f, const Law& m) {
  return m.mu * m.Factor(f) * f + LogTerms{m.mu, m.lambda}.First(f.determinant()) * Cofactor(f);
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
  if (p.nodal_volume) {
    const size_t n = rest.positions.size();
    m.node_volume_.assign(n, 0.0);
    m.node_start_.assign(n + 1, 0);
    for (const Element& e : m.elements_)
      for (int v : e.v) m.node_volume_[v] += e.volume / 4, ++m.node_start_[v + 1];
    for (size_t v = 0; v < n; ++v) m.node_start_[v + 1] += m.node_start_[v];
    m.node_elements_.resize(m.elements_.size() * 4);
    std::vector<int> fill(m.node_start_.begin(), m.node_start_.end() - 1);
    for (size_t e = 0; e < m.elements_.size(); ++e)
      for (int v : m.elements_[e].v) m.node_elements_[fill[v]++] = static_cast<int>(e);
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
  if (node_volume_.empty() || !std::isfinite(energy)) return energy;
  std::vector<double> j;
  return NodalJacobians(x_, j) ? energy + NodalEnergy(j) : kInf;
}

bool HyperelasticFem::NodalJacobians(const std::vector<Vec3>& x, std::vector<double>& j) const {
  j.assign(x.size(), 0.0);
  for (const Element& e : elements_) {
    const double je = Deformation(e, x).determinant();
    if (!std::isfinite(je)) return false;
    for (int v : e.v) j[v] += e.volume * je / 4;
  }
  for (size_t v = 0; v < j.size(); ++v) j[v] = node_volume_[v] > 0 ? j[v] / node_volume_[v] : 1.0;
  return true;
}

std::vector<double> HyperelasticFem::ElementPressures(const std::vector<double>& j) const {
  std::vector<double> out(elements_.size(), 0.0);
  for (size_t e = 0; e < elements_.size(); ++e)
    for (int v : elements_[e].v) out[e] += 0.25 * LogTerms{0, lambda_}.First(j[v]);
  return out;
}

double HyperelasticFem::NodalEnergy(const std::vector<double>& j) const {
  double energy = 0;
  for (size_t v = 0; v < j.size(); ++v)
    energy += node_volume_[v] * LogTerms{0, lambda_}.Value(j[v]);
  return energy;
}

// Σ_n V_n·Φ''(J_n)·∇J_n ∇J_nᵀ, ∇J_n = Σ_{e ∋ n} ∇v_e / (4·V_n), ∇v_e = −NodalForces(J·F⁻ᵀ) (the
// gradient of the element's current volume V·J).
void HyperelasticFem::NodalTangent(const std::vector<double>& j,
                                   std::vector<Eigen::Triplet<double>>& out) const {
  std::vector<int> verts;
  std::vector<Vec3> grad;
  for (size_t n = 0; n < node_volume_.size(); ++n) {
    if (!(node_volume_[n] > 0)) continue;
    verts.clear();
    grad.clear();
    for (int k = node_start_[n]; k < node_start_[n + 1]; ++k) {
      const Element& e = elements_[node_elements_[k]];
      const Mat3 f = Deformation(e, x_);
      const auto dv = NodalForces(Cofactor(f), e.dm_inv, e.volume);
      for (int a = 0; a < 4; ++a) {
        const auto at = std::find(verts.begin(), verts.end(), e.v[a]) - verts.begin();
        if (at == static_cast<long>(verts.size()))
          verts.push_back(e.v[a]), grad.push_back(Vec3::Zero());
        grad[at] -= dv[a] / (4 * node_volume_[n]);
      }
    }
    const double weight = node_volume_[n] * LogTerms{0, lambda_}.Second(j[n]);
    for (size_t a = 0; a < verts.size(); ++a)
      for (size_t b = 0; b < verts.size(); ++b) {
        const Mat3 block = weight * grad[a] * grad[b].transpose();
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            out.emplace_back(3 * verts[a] + r, 3 * verts[b] + c, block(r, c));
      }
  }
}

Eigen::VectorXd HyperelasticFem::InternalForces() const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(x_.size()));
  std::vector<double> j, pressure;
  if (!node_volume_.empty() && NodalJacobians(x_, j)) pressure = ElementPressures(j);
  for (const Element& e : elements_) {
    const size_t i = &e - elements_.data();
    const Mat3 def = Deformation(e, x_);
    Mat3 p = ElementStress(i, def);
    if (!pressure.empty()) p += pressure[i] * Cofactor(def);
    const auto nodal = NodalForces(p, e.dm_inv, e.volume);
    for (int a = 0; a < 4; ++a) f.segment<3>(3 * e.v[a]) += nodal[a];
  }
  return f;
}

// Column (a, c) of each element's 12×12 tangent: the forces' change for a unit move of vertex a
// along axis c, negated (K = −∂f/∂x); `add(e, slot, row, col, value)` takes each entry, slot its
// place among the element's 144 ((a·3 + c)·12 + b·3 + r).
template <class Add>
void HyperelasticFem::ElementTangents(const std::vector<double>& pressure, Add&& add) const {
  const double lambda = node_volume_.empty() ? lambda_ : 0.0;  // the elements' own volumetric part
  for (const Element& e : elements_) {
    const size_t i = &e - elements_.data();
    // dP = μ·e·(dF + 2b·(F:dF)·F) + g''(J)·(cof F : dF)·cof F + (g'(J) + p̄)·d(cof F).
    const Mat3 f = Deformation(e, x_), cof = Cofactor(f);
    const LogTerms g{mu_, lambda};
    const double det = f.determinant(), factor = Law{mu_, lambda_, b_}.Factor(f);
    const double g2 = g.Second(det), g1 = g.First(det) + pressure[i];
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c) {
        Mat3 d_ds = Mat3::Zero();
        if (a == 0)
          d_ds.row(c).setConstant(-1);
        else
          d_ds(c, a - 1) = 1;
        const Mat3 df = d_ds * e.dm_inv;
        Mat3 dp = mu_ * factor * (df + 2 * b_ * (f.array() * df.array()).sum() * f) +
                  g2 * (cof.array() * df.array()).sum() * cof + g1 * CofactorChange(f, df);
        if (!s_hist_.empty()) dp = scale_ * dp + df * s_hist_[i];
        const auto dforces = NodalForces(dp, e.dm_inv, e.volume);
        for (int b = 0; b < 4; ++b)
          for (int r = 0; r < 3; ++r)
            add(i, (a * 3 + c) * 12 + b * 3 + r, 3 * e.v[b] + r, 3 * e.v[a] + c, -dforces[b][r]);
      }
  }
}

// The elements' stencil, once: the matrix's pattern and each element entry's place in its values,
// so that each Newton step adds into it (assembling from triplets took a third of a dynamic step).
void HyperelasticFem::BuildPattern() const {
  const auto n = 3 * static_cast<Eigen::Index>(x_.size());
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(elements_.size() * 144);
  for (const Element& e : elements_)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) entries.emplace_back(3 * e.v[b] + r, 3 * e.v[a] + c, 0.0);
  pattern_.resize(n, n);
  pattern_.setFromTriplets(entries.begin(), entries.end());
  pattern_.makeCompressed();
  slot_.resize(elements_.size() * 144);
  const int* outer = pattern_.outerIndexPtr();
  const int* inner = pattern_.innerIndexPtr();
  for (const Element& e : elements_)
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c)
        for (int b = 0; b < 4; ++b)
          for (int r = 0; r < 3; ++r) {
            const int col = 3 * e.v[a] + c, row = 3 * e.v[b] + r;
            const int* at = std::lower_bound(inner + outer[col], inner + outer[col + 1], row);
            slot_[(&e - elements_.data()) * 144 + (a * 3 + c) * 12 + b * 3 + r] =
                static_cast<int>(at - inner);
          }
}

Eigen::SparseMatrix<double> HyperelasticFem::Tangent() const {
  std::vector<double> j, pressure(elements_.size(), 0.0);
  if (!node_volume_.empty()) {  // a wider stencil (the vertices' volumes): assembled each time
    if (NodalJacobians(x_, j)) pressure = ElementPressures(j);
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(elements_.size() * 144);
    ElementTangents(pressure, [&](size_t, int, int row, int col, double v) {
      entries.emplace_back(row, col, v);
    });
    if (!j.empty()) NodalTangent(j, entries);
    const auto n = 3 * static_cast<Eigen::Index>(x_.size());
    Eigen::SparseMatrix<double> k(n, n);
    k.setFromTriplets(entries.begin(), entries.end());
    return k;
  }
  if (pattern_.nonZeros() == 0) BuildPattern();
  Eigen::SparseMatrix<double> k = pattern_;
  double* values = k.valuePtr();
  ElementTangents(pressure, [&](size_t e, int slot, int, int, double v) {
    values[slot_[e * 144 + static_cast<size_t>(slot)]] += v;
  });
  return k;
}

double HyperelasticFem::ElementDensity(size_t e, const Mat3& f) const {
  const double psi = Density(f, {mu_, node_volume_.empty() ? lambda_ : 0.0, b_});
  if (s_hist_.empty() || !std::isfinite(psi)) return psi;
  const Mat3 strain = f.transpose() * f - Mat3::Identity();
  return scale_ * psi + 0.5 * (s_hist_[e].array() * strain.array()).sum();
}

Mat3 HyperelasticFem::ElementStress(size_t e, const Mat3& f) const {
  const Mat3 p = Stress(f, {mu_, node_volume_.empty() ? lambda_ : 0.0, b_});
  return s_hist_.empty() ? p : Mat3(scale_ * p + f * s_hist_[e]);
}

Status CheckPronyTerms(const std::vector<PronyTerm>& terms) {
  double sum = 0;
  for (size_t i = 0; i < terms.size(); ++i) {
    const PronyTerm& t = terms[i];
    if (!(std::isfinite(t.g) && t.g >= 0 && std::isfinite(t.tau) && t.tau > 0))
      return InvalidArgument("relaxation[" + std::to_string(i) + "]",
                             "g must be >= 0 and tau > 0 s, both finite");
    sum += t.g;
  }
  if (!(sum < 1)) return InvalidArgument("relaxation", "the terms' g must sum to less than 1");
  return Status::Ok();
}

PronyDecay DecayOver(const PronyTerm& term, double h) {
  const double x = std::max(h, 0.0) / term.tau;
  return {std::exp(-x), x > 1e-12 ? -std::expm1(-x) / x : 1.0};
}

Status HyperelasticFem::SetRelaxation(std::vector<PronyTerm> terms) {
  if (!node_volume_.empty() && !terms.empty())
    return InvalidArgument("relaxation",
                           "not with nodal_volume: the relaxation's history is kept per element");
  if (Status ok = CheckPronyTerms(terms); !ok.ok()) return ok;
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

Status HyperelasticFem::SetDensity(double density) {
  if (!(std::isfinite(density) && density >= 0))
    return InvalidArgument("density", "the density must be finite and >= 0 kg/m³");
  mass_.clear();
  velocity_.assign(x_.size(), Vec3::Zero());
  if (density == 0) return Status::Ok();
  mass_.assign(x_.size(), 0.0);
  for (const Element& e : elements_)
    for (int v : e.v) mass_[v] += density * e.volume / 4;
  return Status::Ok();
}

double HyperelasticFem::KineticEnergy() const {
  double k = 0;
  for (size_t i = 0; i < mass_.size(); ++i) k += 0.5 * mass_[i] * velocity_[i].squaredNorm();
  return k;
}

double HyperelasticFem::LoadPotential() const {
  double p = 0;
  for (size_t i = 0; i < x_.size(); ++i) p -= f_ext_[i].dot(x_[i]);
  return p;
}

HyperelasticSolve HyperelasticFem::Step(double dt, double tolerance) {
  time_ += dt;
  if (mass_.empty()) return RelaxingStep(dt, tolerance);
  // x̂ = x_n + h·v_n on the free coordinates; a held one is where Hold put it. Newton starts from
  // x̂ or x_n, whichever has the lower incremental potential: a fast bar's x̂ can be stretched
  // past what the exponential law can count (e^{b(I1−3)} overflows), x_n never is.
  const std::vector<Vec3> start = x_;
  predicted_ = x_;
  for (size_t i = 0; i < x_.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (!held_[3 * i + c]) predicted_[i][c] += dt * velocity_[i][c];
  inertia_ = 1 / (dt * dt);
  if (Potential(predicted_) < Potential(start)) x_ = predicted_;
  const HyperelasticSolve out = RelaxingStep(dt, tolerance);
  inertia_ = 0;
  for (size_t i = 0; i < x_.size(); ++i) velocity_[i] = (x_[i] - start[i]) / dt;
  return out;
}

HyperelasticSolve HyperelasticFem::RelaxingStep(double dt, double tolerance) {
  if (prony_.empty()) return SolveStatic(50, tolerance);
  const size_t terms = prony_.size();
  std::vector<double> beta(terms), gamma(terms);
  scale_ = 1;
  for (size_t i = 0; i < terms; ++i) {
    const PronyDecay d = DecayOver(prony_[i], dt);
    beta[i] = d.beta;
    gamma[i] = d.gamma;
    scale_ += prony_[i].g * (gamma[i] - 1);  // g∞ + Σ g_i·γ_i, with g∞ = 1 − Σ g_i
  }
  for (size_t e = 0; e < elements_.size(); ++e) {
    s_hist_[e].setZero();
    for (size_t i = 0; i < terms; ++i)
      s_hist_[e] += beta[i] * h_[e * terms + i] - prony_[i].g * gamma[i] * s_prev_[e];
  }
  const HyperelasticSolve out = SolveStatic(50, tolerance);
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
  if (!node_volume_.empty()) {
    std::vector<double> j;
    if (!NodalJacobians(x, j)) return kInf;
    potential += NodalEnergy(j);
  }
  for (size_t i = 0; i < x.size(); ++i) potential -= f_ext_[i].dot(x[i]);
  if (inertia_ > 0)
    for (size_t i = 0; i < x.size(); ++i)
      potential += 0.5 * inertia_ * mass_[i] * (x[i] - predicted_[i]).squaredNorm();
  return potential;
}

Eigen::VectorXd HyperelasticFem::FreeResidual() const {
  Eigen::VectorXd r = InternalForces();
  for (size_t i = 0; i < x_.size(); ++i)
    r.segment<3>(3 * static_cast<Eigen::Index>(i)) += f_ext_[i];
  if (inertia_ > 0)  // the inertial force −m·(x − x̂)/h²
    for (size_t i = 0; i < x_.size(); ++i)
      r.segment<3>(3 * static_cast<Eigen::Index>(i)) -=
          inertia_ * mass_[i] * (x_[i] - predicted_[i]);
  for (Eigen::Index k = 0; k < r.size(); ++k)
    if (held_[k]) r[k] = 0;
  return r;
}

// A dynamic step's system K + M/h² is well conditioned (the masses' term is of the stiffness's
// size at h = 1 ms): conjugate gradients preconditioned by its diagonal, as VegaFEM's implicit
// integrators solve it, to a residual of a fraction of what Newton must reach (`target`, N),
// in a ninth of the factorisation's time on hyper-step's bar. A static one (K alone, ill
// conditioned near incompressibility) and a CG that fails are factorised: nested dissection
// (METIS) as the linear FEM's solves, a fraction of the minimum-degree ordering's fill and time.
Eigen::VectorXd HyperelasticFem::NewtonDirection(const Eigen::SparseMatrix<double>& k,
                                                 const Eigen::VectorXd& r, double target) const {
  if (inertia_ > 0) {
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg(k);
    cg.setTolerance(std::clamp(0.5 * target / r.norm(), 1e-12, 0.1));
    cg.setMaxIterations(static_cast<Eigen::Index>(std::max<size_t>(1000, x_.size())));
    Eigen::VectorXd d = cg.solve(r);
    if (cg.info() == Eigen::Success && d.allFinite()) return d;
  }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::MetisOrdering<int>>
      solver(k);
  return solver.info() == Eigen::Success ? Eigen::VectorXd(solver.solve(r)) : r;
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
      // A dynamic step's inertial force m·(x − x̂)/h² is known no better than its positions'
      // rounding: at h = 30 µs that floor is above 1e-10 of a 0.04 N load.
      if (inertia_ > 0) scale = std::max(scale, 1e-4 * inertia_ * mass_[k / 3] * x_[k / 3].norm());
    }
    const Eigen::VectorXd r = FreeResidual();
    out.residual = r.lpNorm<Eigen::Infinity>() / scale;
    if (!std::isfinite(out.residual)) break;  // an overflowing force: no answer here
    if (out.residual < tolerance) return out.converged = true, out;
    if (out.iterations == max_iterations) break;
    // Newton's direction on the free coordinates (held ones pinned by an identity row).
    Eigen::SparseMatrix<double> k = Tangent();
    if (inertia_ > 0)
      for (Eigen::Index d = 0; d < k.rows(); ++d) k.coeffRef(d, d) += inertia_ * mass_[d / 3];
    for (int col = 0; col < k.outerSize(); ++col)
      for (Eigen::SparseMatrix<double>::InnerIterator it(k, col); it; ++it)
        if (held_[it.row()] || held_[it.col()]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    Eigen::VectorXd d = NewtonDirection(k, r, tolerance * scale);
    if (!(d.allFinite() && r.dot(d) > 0)) d = r;  // not a descent: the steepest one
    // Backtracking on the potential (Armijo); an inverted element pays the continued g(J).
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
