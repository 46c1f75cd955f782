#include "common/tissue/fem.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <iostream>  // Eigen's METIS bridge writes to std::cerr without including it itself
#include <thread>
#include <type_traits>
#include <utility>

#include <Eigen/MetisSupport>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "common/tissue/block_cg.h"
#include "common/tissue/extrapolation.h"
#include "common/tissue/simd.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// The rotation R maximising tr(Rᵀ A) (the polar decomposition's), by rotating R towards A:
// R ← exp([ω]) R. With g = Σ_i r_i × a_i (r_i, a_i the columns) and P = sym(A Rᵀ), the objective
// near R is g·ω − ½ ωᵀ (tr(P) I − P) ω, so Newton's step is ω = (tr(P) I − P)⁻¹ g: quadratic
// convergence, 1–2 iterations warm-started. Müller et al. 2016 (Algorithm 1) replace the matrix
// by tr(P) I, which always converges but only linearly, by about a third per iteration near a
// rotation (six iterations to 1e-6 rad from a step's change); that step is kept for when the
// matrix is not positive definite (an element far from a rotation of its rest shape, or
// inverted). Always a proper rotation. A small ω is applied to first order
// (q ← q + ½·(0, ω)·q, then normalised), saving the sine and cosine of the axis–angle form.
// `r` receives q's matrix (the one the last iteration tested, when it converged: no second
// conversion).
[[gnu::always_inline]] inline void ExtractRotation(const Mat3& a, Eigen::Quaterniond& q,
                                                   int max_iterations, Mat3& r) {
  for (int it = 0; it < max_iterations; ++it) {
    r = q.toRotationMatrix();
    const Vec3 g = r.col(0).cross(a.col(0)) + r.col(1).cross(a.col(1)) + r.col(2).cross(a.col(2));
    const Mat3 m = a * r.transpose();
    const double tr = m.trace();
    Mat3 h = -0.5 * (m + m.transpose());
    h.diagonal().array() += tr;
    // Positive definite (Sylvester): Newton; otherwise Müller's scalar step.
    const double minor2 = h(0, 0) * h(1, 1) - h(0, 1) * h(1, 0), det = h.determinant();
    const bool newton = tr > 0 && h(0, 0) > 0 && minor2 > 0 && det > 1e-12 * tr * tr * tr;
    const Vec3 omega = newton ? Vec3(h.inverse() * g) : Vec3(g * (1.0 / (std::abs(tr) + 1e-9)));
    const double w = omega.norm();
    if (!(w > 1e-6)) return;  // converged (1e-6 rad); also stops on a non-finite input
    if (w < 1e-2) {
      const Eigen::Quaterniond dq(0.0, 0.5 * omega.x(), 0.5 * omega.y(), 0.5 * omega.z());
      q.coeffs() += (dq * q).coeffs();
    } else {
      q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * q;
    }
    q.normalize();
    // Newton's error after a step of w is of order w² (its convergence is quadratic): below
    // 1e-3 rad the next step would be below the 1e-6 rad test, so q is taken untested.
    if (newton && w < 1e-3) break;
  }
  r = q.toRotationMatrix();  // the last update untested (converged, or the iteration limit)
}

}  // namespace

struct FemModel::Impl {
  FemParams params;
  geometry::TetMesh rest;
  std::vector<Vec3> x, v, f_ext;
  std::vector<double> mass;  // lumped, kg per vertex
  std::vector<uint8_t> is_fixed;
  // Per element: rest shape inverse, shape gradients g_a (rest), V·λ and V·μ, rotation.
  // (The 12×12 stiffness is never stored: K_ab = V·(λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I)
  // costs less to rebuild from g than to load, and the forces need only σ·g_a.)
  std::vector<Mat3> dm_inverse;
  std::vector<std::array<Vec3, 4>> grad;
  std::vector<double> v_lambda, v_mu;
  std::vector<Eigen::Quaterniond> rotation;
  std::vector<Mat3> rotation_matrix;
  // Block CSR of the vertex adjacency: row r's blocks are [row_start[r], row_start[r+1]).
  std::vector<int> row_start, col;
  std::vector<Mat3> blocks;  // K (corotated), assembled each step; one block of padding at the end
  std::vector<int> diag_slot;             // slot of (r, r)
  std::vector<std::array<int, 16>> slot;  // element (a, b) → block index
  std::vector<Vec3> dv, rhs, tmp;
  BlockCg cg;
  // The last four steps' Δv, history[newest] the newest (rotating), and the degree of the next
  // step's first guess (extrapolation.h).
  std::array<std::vector<Vec3>, 4> history;
  int newest = 0, extrapolation = 1;
  int inverted = 0;

  int n() const { return static_cast<int>(x.size()); }

  // `iterations`: the rotation iteration's limit; warm-started, a dynamic step usually needs one
  // or two, a sudden large rotation more.
  VSURG_SIMD_CLONES
  void UpdateRotations(int iterations = 20) {
    inverted = 0;
    const int te = static_cast<int>(rest.tetrahedra.size());
    for (int e = 0; e < te; ++e) {
      const auto& t = rest.tetrahedra[e];
      Mat3 ds;
      ds.col(0) = x[t[1]] - x[t[0]];
      ds.col(1) = x[t[2]] - x[t[0]];
      ds.col(2) = x[t[3]] - x[t[0]];
      const Mat3 f = ds * dm_inverse[e];
      if (f.determinant() <= 0) ++inverted;
      if (params.corotational) ExtractRotation(f, rotation[e], iterations, rotation_matrix[e]);
    }
  }

  // Rotated small strain of element e: H = Σ_b u_b g_bᵀ with u_b = Rᵀ x_b − X_b, ε = sym(H),
  // and the stress σ·V = V·(λ tr(ε) I + 2μ ε).
  Mat3 StressVolume(int e) const {
    const auto& t = rest.tetrahedra[e];
    const Mat3& rot = rotation_matrix[e];
    Mat3 h = Mat3::Zero();
    for (int b = 0; b < 4; ++b)
      h.noalias() += (rot.transpose() * x[t[b]] - rest.positions[t[b]]) * grad[e][b].transpose();
    const Mat3 eps = 0.5 * (h + h.transpose());
    return v_lambda[e] * eps.trace() * Mat3::Identity() + 2.0 * v_mu[e] * eps;
  }

  // Elastic forces f_a = −R·σ·V·g_a (N) into out, and, when `assemble`, the corotated
  // stiffness blocks R·K_ab·Rᵀ = V·(λ h_a h_bᵀ + μ h_b h_aᵀ + μ (g_a·g_b) I), h = R·g.
  void ForcesAndStiffness(std::vector<Vec3>& out, bool assemble) {
    std::fill(out.begin(), out.end(), Vec3::Zero());
    if (assemble) std::fill(blocks.begin(), blocks.end(), Mat3::Zero());
    const int te = static_cast<int>(rest.tetrahedra.size());
    for (int e = 0; e < te; ++e) {
      const auto& t = rest.tetrahedra[e];
      const Mat3& rot = rotation_matrix[e];
      const Mat3 rs = rot * StressVolume(e);
      Vec3 hg[4];
      for (int a = 0; a < 4; ++a) {
        out[t[a]].noalias() -= rs * grad[e][a];
        hg[a] = rot * grad[e][a];
      }
      if (assemble) AddElementBlocks(e, hg);
    }
  }

  // Element e's sixteen blocks into the CSR. A block's nine entries (column-major) are two
  // four-lane vectors and one scalar: entry r + 3c of h_a h_bᵀ is h_a[r]·h_b[c], so with the
  // lane patterns P1(h) = (h0 h1 h2 h0), P2(h) = (h1 h2 h0 h1) for the rows and Q1(h) =
  // (h0 h0 h0 h1), Q2(h) = (h1 h1 h2 h2) for the columns, entries 0–3 are P1(h_a)·Q1(h_b) and
  // 4–7 are P2(h_a)·Q2(h_b); the (b, a) block is the same with a and b swapped.
  VSURG_SIMD_CLONES
  void AddElementBlocks(int e, const Vec3 (&hg)[4]) {
    using simd::V4;
    V4 p1[4], p2[4], q1[4], q2[4];
    for (int a = 0; a < 4; ++a) {
      const Vec3& h = hg[a];
      p1[a] = V4{h.x(), h.y(), h.z(), h.x()}, p2[a] = V4{h.y(), h.z(), h.x(), h.y()};
      q1[a] = V4{h.x(), h.x(), h.x(), h.y()}, q2[a] = V4{h.y(), h.y(), h.z(), h.z()};
    }
    const double vl = v_lambda[e], vm = v_mu[e];
    for (int a = 0; a < 4; ++a) {
      for (int b = a; b < 4; ++b) {
        const double d = vm * grad[e][a].dot(grad[e][b]);  // μV (g_a·g_b) on the diagonal
        const V4 diag{d, 0.0, 0.0, 0.0};
        const V4 x1 = p1[a] * q1[b], y1 = p1[b] * q1[a], x2 = p2[a] * q2[b], y2 = p2[b] * q2[a];
        const double x3 = hg[a].z() * hg[b].z();
        double* k = blocks[slot[e][a * 4 + b]].data();
        simd::AddTo(k, vl * x1 + vm * y1 + diag);
        simd::AddTo(k + 4, vl * x2 + vm * y2 + diag);
        k[8] += (vl + vm) * x3 + d;
        if (b == a) continue;
        double* kt = blocks[slot[e][b * 4 + a]].data();
        simd::AddTo(kt, vl * y1 + vm * x1 + diag);
        simd::AddTo(kt + 4, vl * y2 + vm * x2 + diag);
        kt[8] += (vl + vm) * x3 + d;
      }
    }
  }
  void Forces(std::vector<Vec3>& out) { ForcesAndStiffness(out, false); }
  void Assemble() { ForcesAndStiffness(tmp, true); }

  // A = c_m·M + c_k·K over the block CSR (block_cg.h).
  BlockMatrix Matrix(double c_m, double c_k) const {
    return {n(),
            c_m,
            c_k,
            row_start.data(),
            col.data(),
            diag_slot.data(),
            blocks.data(),
            mass.data(),
            is_fixed.data()};
  }
  // out = (c_m·M + c_k·K)·in on free vertices; fixed rows are zero.
  void Apply(double c_m, double c_k, const std::vector<Vec3>& in, std::vector<Vec3>& out) const {
    Multiply(Matrix(c_m, c_k), in, out);
  }
};

FemModel::FemModel(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FemModel::FemModel(FemModel&&) noexcept = default;
FemModel& FemModel::operator=(FemModel&&) noexcept = default;
FemModel::~FemModel() = default;

Expected<FemModel> FemModel::Create(const geometry::TetMesh& mesh, const FemParams& params,
                                    const std::vector<int>& fixed) {
  if (params.nodal_volume)
    return InvalidArgument("nodal_volume",
                           "the volume at the vertices is for a static response's K₀ "
                           "(FemStaticResponse); the corotational model keeps it per element");
  if (!(params.young > 0) || !std::isfinite(params.young))
    return InvalidArgument("young", "Young's modulus must be > 0 Pa");
  if (!(params.poisson > -1.0 && params.poisson < 0.5))
    return InvalidArgument("poisson", "Poisson's ratio must be within (-1, 0.5)");
  if (!(params.density > 0) || !std::isfinite(params.density))
    return InvalidArgument("density", "must be > 0 kg/m³");
  if (!(params.mass_damping >= 0) || !(params.stiffness_damping >= 0))
    return InvalidArgument("damping", "Rayleigh coefficients must be >= 0");
  if (params.max_cg_iterations < 1 || !(params.cg_tolerance > 0))
    return InvalidArgument("cg", "iterations >= 1 and tolerance > 0");
  if (!(params.cg_extrapolation >= 1 && params.cg_extrapolation <= 3))
    return InvalidArgument("cg_extrapolation", "the first guess's degree must be 1 to 3");
  if (Status s = geometry::Validate(mesh, 1e-15); !s.ok()) return s.error();
  const int nv = mesh.VertexCount(), te = mesh.TetCount();
  if (te == 0) return InvalidArgument("mesh", "no tetrahedra");
  const std::vector<double>& scale = params.element_stiffness_scale;
  if (!scale.empty() && static_cast<int>(scale.size()) != te)
    return InvalidArgument("element_stiffness_scale", "one factor per tetrahedron");
  for (double k : scale)
    if (!std::isfinite(k) || !(k > 0))
      return InvalidArgument("element_stiffness_scale", "each factor must be finite and > 0");

  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  m.params = params;
  m.rest = mesh;
  m.x = mesh.positions;
  m.v.assign(nv, Vec3::Zero());
  m.f_ext.assign(nv, Vec3::Zero());
  m.mass.assign(nv, 0.0);
  m.is_fixed.assign(nv, 0);
  for (int f : fixed) {
    if (f < 0 || f >= nv) return InvalidArgument("fixed", "vertex index out of range");
    m.is_fixed[f] = 1;
  }
  const double e_mod = params.young, nu = params.poisson;
  const double lambda = e_mod * nu / ((1 + nu) * (1 - 2 * nu));
  const double mu = e_mod / (2 * (1 + nu));
  m.dm_inverse.resize(te);
  m.grad.resize(te);
  m.v_lambda.resize(te);
  m.v_mu.resize(te);
  m.rotation.assign(te, Eigen::Quaterniond::Identity());
  m.rotation_matrix.assign(te, Mat3::Identity());
  for (int e = 0; e < te; ++e) {
    const auto& t = mesh.tetrahedra[e];
    Mat3 dm;
    dm.col(0) = mesh.positions[t[1]] - mesh.positions[t[0]];
    dm.col(1) = mesh.positions[t[2]] - mesh.positions[t[0]];
    dm.col(2) = mesh.positions[t[3]] - mesh.positions[t[0]];
    const double volume = dm.determinant() / 6.0;
    const Mat3 inv = dm.inverse();
    m.dm_inverse[e] = inv;
    // Shape gradients: rows of D_m⁻¹ for vertices 1..3, minus their sum for vertex 0.
    Vec3 g[4];
    for (int a = 1; a < 4; ++a) g[a] = inv.row(a - 1).transpose();
    g[0] = -(g[1] + g[2] + g[3]);
    for (int a = 0; a < 4; ++a) m.grad[e][a] = g[a];
    const double k = scale.empty() ? 1.0 : scale[e];
    m.v_lambda[e] = k * volume * lambda;
    m.v_mu[e] = k * volume * mu;
    for (int a = 0; a < 4; ++a) m.mass[t[a]] += params.density * volume / 4.0;
  }
  // Block pattern: every vertex pair sharing an element.
  std::vector<std::vector<int>> adj(nv);
  for (const auto& t : mesh.tetrahedra)
    for (int a : t)
      for (int b : t) adj[a].push_back(b);
  m.row_start.assign(nv + 1, 0);
  for (int i = 0; i < nv; ++i) {
    auto& row = adj[i];
    row.push_back(i);
    std::sort(row.begin(), row.end());
    row.erase(std::unique(row.begin(), row.end()), row.end());
    m.row_start[i + 1] = m.row_start[i] + static_cast<int>(row.size());
    m.col.insert(m.col.end(), row.begin(), row.end());
  }
  m.blocks.assign(m.col.size() + 1, Mat3::Zero());  // + the block product's padding
  auto find_slot = [&](int r, int c) {
    const auto first = m.col.begin() + m.row_start[r], last = m.col.begin() + m.row_start[r + 1];
    return static_cast<int>(std::lower_bound(first, last, c) - m.col.begin());
  };
  m.diag_slot.resize(nv);
  for (int i = 0; i < nv; ++i) m.diag_slot[i] = find_slot(i, i);
  m.slot.resize(te);
  for (int e = 0; e < te; ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        m.slot[e][a * 4 + b] = find_slot(mesh.tetrahedra[e][a], mesh.tetrahedra[e][b]);
  for (auto* s :
       {&m.dv, &m.rhs, &m.tmp, &m.history[0], &m.history[1], &m.history[2], &m.history[3]})
    s->assign(nv, Vec3::Zero());
  m.cg.Resize(nv);
  return FemModel(std::move(impl));
}

void FemModel::SetExternalForce(int vertex, const Eigen::Vector3d& f) {
  if (vertex >= 0 && vertex < impl_->n() && f.allFinite()) impl_->f_ext[vertex] = f;
}

void FemModel::ClearExternalForces() {
  std::fill(impl_->f_ext.begin(), impl_->f_ext.end(), Vec3::Zero());
}

FemStepStats FemModel::StepImplicit(double h) {
  Impl& m = *impl_;
  FemStepStats stats;
  if (!(h > 0) || !std::isfinite(h)) return stats;
  m.UpdateRotations(30);
  stats.inverted = m.inverted;
  const double alpha = m.params.mass_damping, beta = m.params.stiffness_damping;
  // rhs = h·(f + f_ext − α·M·v − (β + h)·K·v)
  m.ForcesAndStiffness(m.rhs, true);
  m.Apply(alpha, beta + h, m.v, m.tmp);
  const int nv = m.n();
  for (int i = 0; i < nv; ++i)
    m.rhs[i] = m.is_fixed[i] ? Vec3::Zero() : Vec3(h * (m.rhs[i] + m.f_ext[i] - m.tmp[i]));
  // A = (1 + h·α)·M + (h·β + h²)·K; Δv warm-started from the previous steps'.
  // Δv's first guess extrapolated from the last steps' (extrapolation.h): a tissue in smooth
  // motion changes Δv smoothly, and the CG starts nearer (the twisted bar of vsurg-bench
  // fem-step at 1e-4: 34.9 iterations from the last Δv, 26.8 from the linear guess, 15.5 from
  // the chosen degree). After a sudden change the guess is only a start: CG still converges to
  // the tolerance from it.
  {
    const std::vector<Vec3>&o1 = m.history[m.newest], &o2 = m.history[(m.newest + 3) % 4],
          &o3 = m.history[(m.newest + 2) % 4];
    std::vector<Vec3>& o4 = m.history[(m.newest + 1) % 4];  // the oldest takes the newest
    m.newest = (m.newest + 1) % 4;
    stats.extrapolation = m.extrapolation;
    double miss[3] = {0, 0, 0};
    for (int i = 0; i < nv; ++i) {
      const Vec3 last = m.dv[i];
      if (!m.is_fixed[i]) {
        for (int degree = 1; degree <= 3; ++degree) {
          Vec3 guess;
          Extrapolate(guess, degree, o1[i], o2[i], o3[i], o4[i]);
          miss[degree - 1] += (guess - last).squaredNorm();
        }
      }
      Extrapolate(m.dv[i], m.extrapolation, last, o1[i], o2[i], o3[i]);
      o4[i] = last;
    }
    m.extrapolation = BestDegree(miss[0], miss[1], miss[2], m.params.cg_extrapolation);
  }
  const CgResult cg =
      m.cg.Solve(m.Matrix(1.0 + h * alpha, h * beta + h * h), m.params.preconditioner, m.rhs, m.dv,
                 m.params.max_cg_iterations, m.params.cg_tolerance);
  stats.cg_iterations = cg.iterations;
  stats.residual = cg.residual;
  stats.converged = cg.residual < m.params.cg_tolerance;
  bool finite = true;
  for (int i = 0; i < nv; ++i) finite = finite && m.dv[i].allFinite();
  if (!finite) {  // never let a NaN into the state: drop this step's change
    std::fill(m.dv.begin(), m.dv.end(), Vec3::Zero());
    for (auto& past : m.history) std::fill(past.begin(), past.end(), Vec3::Zero());
    m.extrapolation = 1;
    stats.converged = false;
    return stats;
  }
  for (int i = 0; i < nv; ++i) {
    if (m.is_fixed[i]) continue;
    m.v[i] += m.dv[i];
    m.x[i] += h * m.v[i];
  }
  return stats;
}

FemStaticStats FemModel::SolveStatic(int max_iterations, double tolerance) {
  Impl& m = *impl_;
  FemStaticStats stats;
  const int nv = m.n();
  double ext = 0;
  for (int i = 0; i < nv; ++i)
    if (!m.is_fixed[i]) ext += m.f_ext[i].squaredNorm();
  ext = std::sqrt(ext);
  if (!(ext > 0)) ext = 1;
  // Nested dissection (METIS), as FemStaticResponse's default: on a wide block (the palpation
  // pad at 40 × 40 × 16 cells) Eigen's minimum degree filled the factor for minutes.
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::MetisOrdering<int>>
      solver;
  Eigen::SparseMatrix<double> k(3 * nv, 3 * nv);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(m.blocks.size() * 9);
  bool factorised = false;
  double last_residual = 0;
  for (int it = 0; it < max_iterations; ++it) {
    m.UpdateRotations();
    m.Forces(m.rhs);
    double res = 0;
    Eigen::VectorXd b(3 * nv);
    for (int i = 0; i < nv; ++i) {
      const Vec3 g = m.is_fixed[i] ? Vec3::Zero() : Vec3(m.rhs[i] + m.f_ext[i]);
      b.segment<3>(3 * i) = g;
      res += g.squaredNorm();
    }
    stats.residual = std::sqrt(res) / ext;
    stats.iterations = it;
    if (stats.residual < tolerance) {
      stats.converged = true;
      return stats;
    }
    // Modified Newton: keep the factorisation while it still cuts the residual tenfold per
    // iteration (small rotations); re-assemble and re-factorise when it does not.
    if (!factorised || stats.residual > 0.1 * last_residual) {
      m.Assemble();
      triplets.clear();
      for (int i = 0; i < nv; ++i) {
        for (int s = m.row_start[i]; s < m.row_start[i + 1]; ++s) {
          const int j = m.col[s];
          if (m.is_fixed[i] || m.is_fixed[j]) continue;
          for (int a = 0; a < 3; ++a)
            for (int c = 0; c < 3; ++c)
              triplets.emplace_back(3 * i + a, 3 * j + c, m.blocks[s](a, c));
        }
        if (m.is_fixed[i])
          for (int a = 0; a < 3; ++a) triplets.emplace_back(3 * i + a, 3 * i + a, 1.0);
      }
      k.setFromTriplets(triplets.begin(), triplets.end());
      if (!factorised) solver.analyzePattern(k);
      solver.factorize(k);
      if (solver.info() != Eigen::Success) return stats;
      factorised = true;
    }
    last_residual = stats.residual;
    const Eigen::VectorXd dx = solver.solve(b);
    if (!dx.allFinite()) return stats;
    for (int i = 0; i < nv; ++i)
      if (!m.is_fixed[i]) m.x[i] += dx.segment<3>(3 * i);
  }
  m.UpdateRotations();
  m.Forces(m.rhs);
  double res = 0;
  for (int i = 0; i < nv; ++i)
    if (!m.is_fixed[i]) res += (m.rhs[i] + m.f_ext[i]).squaredNorm();
  stats.residual = std::sqrt(res) / ext;
  stats.iterations = max_iterations;
  stats.converged = stats.residual < tolerance;
  return stats;
}

void FemModel::SetPosition(int vertex, const Eigen::Vector3d& x) {
  if (vertex >= 0 && vertex < impl_->n() && x.allFinite()) impl_->x[vertex] = x;
}

void FemModel::Reset() {
  Impl& m = *impl_;
  m.x = m.rest.positions;
  std::fill(m.v.begin(), m.v.end(), Vec3::Zero());
  std::fill(m.dv.begin(), m.dv.end(), Vec3::Zero());
  for (auto& past : m.history) std::fill(past.begin(), past.end(), Vec3::Zero());
  m.extrapolation = 1;
  std::fill(m.rotation.begin(), m.rotation.end(), Eigen::Quaterniond::Identity());
  std::fill(m.rotation_matrix.begin(), m.rotation_matrix.end(), Mat3::Identity());
}

const std::vector<Eigen::Vector3d>& FemModel::positions() const {
  return impl_->x;
}
const std::vector<Eigen::Vector3d>& FemModel::velocities() const {
  return impl_->v;
}
const geometry::TetMesh& FemModel::rest() const {
  return impl_->rest;
}
int FemModel::TetCount() const {
  return impl_->rest.TetCount();
}
int FemModel::VertexCount() const {
  return impl_->n();
}

double FemModel::KineticEnergy() const {
  double e = 0;
  for (int i = 0; i < impl_->n(); ++i) e += 0.5 * impl_->mass[i] * impl_->v[i].squaredNorm();
  return e;
}

double FemModel::ElasticEnergy() const {
  // ½·Σ_e V·σ:ε of the rotated small strain.
  const Impl& m = *impl_;
  double e = 0;
  for (int t = 0; t < m.rest.TetCount(); ++t) {
    const auto& tet = m.rest.tetrahedra[t];
    const Mat3& rot = m.rotation_matrix[t];
    Mat3 h = Mat3::Zero();
    for (int b = 0; b < 4; ++b)
      h += (rot.transpose() * m.x[tet[b]] - m.rest.positions[tet[b]]) * m.grad[t][b].transpose();
    const Mat3 eps = 0.5 * (h + h.transpose());
    e += 0.5 * (m.v_lambda[t] * eps.trace() * eps.trace() + 2.0 * m.v_mu[t] * eps.squaredNorm());
  }
  return e;
}

int FemModel::InvertedCount() const {
  const Impl& m = *impl_;
  int n = 0;
  for (int e = 0; e < m.rest.TetCount(); ++e) {
    const auto& t = m.rest.tetrahedra[e];
    Mat3 ds;
    ds.col(0) = m.x[t[1]] - m.x[t[0]];
    ds.col(1) = m.x[t[2]] - m.x[t[0]];
    ds.col(2) = m.x[t[3]] - m.x[t[0]];
    if ((ds * m.dm_inverse[e]).determinant() <= 0) ++n;
  }
  return n;
}

namespace {

// FemParams::nodal_volume's stiffness: per vertex n, (L_n / V_n²)·c_n c_nᵀ with c_n = Σ_{e ∋ n}
// (V_e/4)·(g_a^e at vertex a's coordinates), L_n = Σ_{e ∋ n} V_e·λ_e / 4 and V_n = Σ V_e/4; the
// fixed vertices' rows and columns left out (they are identity rows).
void NodalVolumeStiffness(const geometry::TetMesh& mesh,
                          const std::vector<std::array<Vec3, 4>>& grad,
                          const std::vector<double>& v_lambda, const std::vector<uint8_t>& is_fixed,
                          std::vector<Eigen::Triplet<double>>& out) {
  const int nv = mesh.VertexCount();
  std::vector<std::vector<int>> star(nv);
  std::vector<double> volume(mesh.tetrahedra.size());
  for (size_t e = 0; e < mesh.tetrahedra.size(); ++e) {
    const auto& t = mesh.tetrahedra[e];
    Mat3 dm;
    for (int c = 0; c < 3; ++c) dm.col(c) = mesh.positions[t[c + 1]] - mesh.positions[t[0]];
    volume[e] = dm.determinant() / 6.0;
    for (int a : t) star[a].push_back(static_cast<int>(e));
  }
  std::vector<int> verts;
  std::vector<Vec3> c;
  for (int n = 0; n < nv; ++n) {
    double vn = 0, ln = 0;
    verts.clear();
    c.clear();
    for (int e : star[n]) {
      vn += volume[e] / 4, ln += v_lambda[e] / 4;
      const auto& t = mesh.tetrahedra[e];
      for (int a = 0; a < 4; ++a) {
        const auto at = std::find(verts.begin(), verts.end(), t[a]) - verts.begin();
        if (at == static_cast<std::ptrdiff_t>(verts.size()))
          verts.push_back(t[a]), c.push_back(Vec3::Zero());
        c[at] += volume[e] / 4 * grad[e][a];
      }
    }
    if (!(vn > 0)) continue;
    const double w = ln / (vn * vn);
    for (size_t a = 0; a < verts.size(); ++a) {
      if (is_fixed[verts[a]]) continue;
      for (size_t b = 0; b < verts.size(); ++b) {
        if (is_fixed[verts[b]]) continue;
        const Mat3 block = w * c[a] * c[b].transpose();
        for (int r = 0; r < 3; ++r)
          for (int q = 0; q < 3; ++q)
            out.emplace_back(3 * verts[a] + r, 3 * verts[b] + q, block(r, q));
      }
    }
  }
}

}  // namespace

struct FemStaticResponse::Impl {
  explicit Impl(FemModel m) : model(std::move(m)) {}
  FemModel model;
  // The factor P·K·Pᵀ = L·D·Lᵀ (Eigen's SimplicialLDLT under the FillOrdering asked for, copied
  // out and the solver released: the factor is held once): L's strictly lower entries by column
  // (compressed), 1/D, and P's indices (row i of K is row perm[i] of the permuted system).
  std::vector<int> col_start, row;
  std::vector<double> value, inv_d;
  std::vector<int> perm;

  // Loads *f[0..cols) (cols ≤ B) solved side by side into *out[0..cols): x[i·B + k] is unknown i
  // of load k (scratch, n·B). The same operations in the same order as SimplicialLDLT::solve on
  // each load (its triangular solves skip a zero right-hand entry; subtracting l·0 leaves the
  // same value), so every answer is Eigen's to the last bit.
  template <size_t B>
  void SolveBlock(const std::vector<uint8_t>& is_fixed, const std::vector<Vec3>* const* f,
                  size_t cols, std::vector<Vec3>* const* out, std::vector<double>& x) const {
    const int nv = static_cast<int>(is_fixed.size());
    const size_t n = inv_d.size();
    x.assign(n * B, 0.0);
    for (size_t c = 0; c < cols; ++c) {
      const std::vector<Vec3>& load = *f[c];
      for (int i = 0; i < nv && i < static_cast<int>(load.size()); ++i)
        if (!is_fixed[i] && load[i].allFinite())
          for (int a = 0; a < 3; ++a) x[perm[3 * i + a] * B + c] = load[i][a];
    }
    for (size_t j = 0; j < n; ++j) {  // L·y = P·b
      const double* xj = &x[j * B];
      for (int q = col_start[j]; q < col_start[j + 1]; ++q) {
        double* xi = &x[static_cast<size_t>(row[q]) * B];
        const double lij = value[q];
        for (size_t k = 0; k < B; ++k) xi[k] -= lij * xj[k];
      }
    }
    for (size_t j = 0; j < n; ++j)
      for (size_t k = 0; k < B; ++k) x[j * B + k] = inv_d[j] * x[j * B + k];
    for (size_t j = n; j-- > 0;) {  // Lᵀ·z = D⁻¹·y
      double* xj = &x[j * B];
      for (int q = col_start[j]; q < col_start[j + 1]; ++q) {
        const double* xi = &x[static_cast<size_t>(row[q]) * B];
        const double lij = value[q];
        for (size_t k = 0; k < B; ++k) xj[k] -= lij * xi[k];
      }
    }
    for (size_t c = 0; c < cols; ++c) {  // u = Pᵀ·z
      std::vector<Vec3>& u = *out[c];
      u.assign(nv, Vec3::Zero());
      for (int i = 0; i < nv; ++i)
        if (!is_fixed[i])
          for (int a = 0; a < 3; ++a) u[i][a] = x[perm[3 * i + a] * B + c];
    }
  }
};

FemStaticResponse::FemStaticResponse(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FemStaticResponse::FemStaticResponse(FemStaticResponse&&) noexcept = default;
FemStaticResponse& FemStaticResponse::operator=(FemStaticResponse&&) noexcept = default;
FemStaticResponse::~FemStaticResponse() = default;

Expected<FemStaticResponse> FemStaticResponse::Create(const geometry::TetMesh& mesh,
                                                      const FemParams& params,
                                                      const std::vector<int>& fixed,
                                                      FillOrdering ordering) {
  FemParams per_element = params;
  per_element.nodal_volume = false;
  auto model = FemModel::Create(mesh, per_element, fixed);
  if (!model.ok()) return model.error();
  if (fixed.empty())
    return InvalidArgument("fixed", "a static response needs fixed vertices (else K is singular)");
  auto impl = std::make_unique<Impl>(std::move(*model));
  FemModel::Impl& m = *impl->model.impl_;
  std::vector<double> v_lambda;  // the elements' V·λ, taken out of their blocks to the vertices
  if (params.nodal_volume)
    v_lambda = std::exchange(m.v_lambda, std::vector<double>(m.v_lambda.size(), 0.0));
  m.Assemble();  // at rest: R = I, so these are K₀'s blocks
  const int nv = m.n();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(m.blocks.size() * 9);
  for (int i = 0; i < nv; ++i) {
    if (m.is_fixed[i]) {
      for (int a = 0; a < 3; ++a) triplets.emplace_back(3 * i + a, 3 * i + a, 1.0);
      continue;
    }
    for (int s = m.row_start[i]; s < m.row_start[i + 1]; ++s) {
      const int j = m.col[s];
      if (m.is_fixed[j]) continue;
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) triplets.emplace_back(3 * i + a, 3 * j + c, m.blocks[s](a, c));
    }
  }
  if (!v_lambda.empty()) NodalVolumeStiffness(m.rest, m.grad, v_lambda, m.is_fixed, triplets);
  Eigen::SparseMatrix<double> k(3 * nv, 3 * nv);
  k.setFromTriplets(triplets.begin(), triplets.end());
  // Factorised, the factor copied out (SolveBlock reads it), the solver released.
  const auto factorise = [&]<class Solver>(std::type_identity<Solver>) {
    Solver solver;
    solver.compute(k);
    if (solver.info() != Eigen::Success) return false;
    const auto& l = solver.matrixL().nestedExpression();
    const int n = static_cast<int>(l.cols());
    impl->col_start.assign(1, 0);
    for (int j = 0; j < n; ++j) {
      // As Eigen's own triangular solves read a unit-diagonal factor: the diagonal skipped.
      for (Eigen::SparseMatrix<double>::InnerIterator it(l, j); it; ++it)
        if (it.index() > j)
          impl->row.push_back(static_cast<int>(it.index())), impl->value.push_back(it.value());
      impl->col_start.push_back(static_cast<int>(impl->row.size()));
    }
    // D⁻¹ as Eigen applies it (diag.asDiagonal().inverse(): a multiplication by the reciprocal).
    impl->inv_d.resize(n);
    for (int j = 0; j < n; ++j) impl->inv_d[j] = 1.0 / solver.vectorD()[j];
    const auto& p = solver.permutationP().indices();
    impl->perm.assign(p.data(), p.data() + p.size());
    if (impl->perm.empty()) {
      impl->perm.resize(n);
      for (int i = 0; i < n; ++i) impl->perm[i] = i;
    }
    return true;
  };
  using Sparse = Eigen::SparseMatrix<double>;
  const bool factorised =
      ordering == FillOrdering::kMinimumDegree
          ? factorise(std::type_identity<
                      Eigen::SimplicialLDLT<Sparse, Eigen::Lower, Eigen::AMDOrdering<int>>>{})
          : factorise(std::type_identity<
                      Eigen::SimplicialLDLT<Sparse, Eigen::Lower, Eigen::MetisOrdering<int>>>{});
  if (!factorised)
    return InvalidArgument("mesh",
                           "the stiffness matrix could not be factorised (a part of the "
                           "mesh is not held by any fixed vertex?)");
  return FemStaticResponse(std::move(impl));
}

std::vector<std::vector<Eigen::Vector3d>> FemStaticResponse::SolveMany(
    const std::vector<std::vector<Eigen::Vector3d>>& f, int threads) const {
  const std::vector<uint8_t>& is_fixed = impl_->model.impl_->is_fixed;
  constexpr size_t kBlock = 8;  // loads side by side per pass over the factor
  std::vector<std::vector<Vec3>> out(f.size());
  const size_t blocks = (f.size() + kBlock - 1) / kBlock;
  std::atomic<size_t> next{0};
  auto work = [&] {
    std::vector<double> x;
    for (size_t b; (b = next.fetch_add(1)) < blocks;) {
      const size_t first = b * kBlock, cols = std::min(kBlock, f.size() - first);
      std::array<const std::vector<Vec3>*, kBlock> in{};
      std::array<std::vector<Vec3>*, kBlock> to{};
      for (size_t c = 0; c < cols; ++c) in[c] = &f[first + c], to[c] = &out[first + c];
      impl_->SolveBlock<kBlock>(is_fixed, in.data(), cols, to.data(), x);
    }
  };
  if (threads <= 0) threads = static_cast<int>(std::min(4u, std::thread::hardware_concurrency()));
  const int extra = static_cast<int>(std::min<size_t>(std::max(threads, 1), blocks)) - 1;
  std::vector<std::thread> helpers;
  for (int t = 0; t < extra; ++t) helpers.emplace_back(work);
  work();
  for (std::thread& t : helpers) t.join();
  return out;
}

std::vector<Eigen::Vector3d> FemStaticResponse::Solve(const std::vector<Eigen::Vector3d>& f) const {
  const std::vector<Vec3>* in = &f;
  std::vector<Vec3> u;
  std::vector<Vec3>* to = &u;
  std::vector<double> x;
  impl_->SolveBlock<1>(impl_->model.impl_->is_fixed, &in, 1, &to, x);
  return u;
}

int FemStaticResponse::VertexCount() const {
  return impl_->model.VertexCount();
}
const geometry::TetMesh& FemStaticResponse::rest() const {
  return impl_->model.rest();
}

std::vector<Eigen::Vector3d> TorqueNodalForces(const std::vector<Eigen::Vector3d>& positions,
                                               const std::vector<int>& face_vertices,
                                               const std::vector<double>& area,
                                               const Eigen::Vector3d& centre,
                                               const Eigen::Vector3d& axis, double torque) {
  std::vector<Eigen::Vector3d> out(face_vertices.size(), Vec3::Zero());
  const Vec3 n = axis.normalized();
  double polar = 0;  // Σ A_i |r_i|² ≈ J
  std::vector<Vec3> radial(face_vertices.size());
  for (size_t i = 0; i < face_vertices.size(); ++i) {
    const Vec3 d = positions[face_vertices[i]] - centre;
    radial[i] = d - d.dot(n) * n;
    polar += (i < area.size() ? area[i] : 1.0) * radial[i].squaredNorm();
  }
  if (!(polar > 0)) return out;
  for (size_t i = 0; i < face_vertices.size(); ++i)
    out[i] = torque * (i < area.size() ? area[i] : 1.0) * n.cross(radial[i]) / polar;
  return out;
}

}  // namespace vsurg::tissue
