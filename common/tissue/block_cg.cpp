#include "common/tissue/block_cg.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "common/tissue/simd.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using simd::V4;

// acc += Σ_k B_k·v_col[k] over the slots [k0, k1): each 3×3 block (column-major, 9 doubles) is
// three column loads and three multiply-adds of four lanes (the fourth reads the next block's
// first entry and is dropped; the blocks have one block of padding past the last).
inline void RowSum(V4& acc, const double* blocks, const int* col, int k0, int k1, const double* v) {
  for (int k = k0; k < k1; ++k) {
    const double* b = blocks + 9 * static_cast<ptrdiff_t>(k);
    const double* x = v + 3 * col[k];
    V4 c0, c1, c2;
    simd::Load(c0, b), simd::Load(c1, b + 3), simd::Load(c2, b + 6);
    acc += c0 * x[0] + c1 * x[1] + c2 * x[2];
  }
}

inline Vec3 Three(const V4& acc) {
  return {acc[0], acc[1], acc[2]};
}

const double* Data(const std::vector<Vec3>& v) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double) && sizeof(Mat3) == 9 * sizeof(double));
  return v.data()->data();
}

double FreeNorm(const BlockMatrix& a, const std::vector<Vec3>& v) {
  double s = 0;
  for (int i = 0; i < a.n; ++i)
    if (!a.is_fixed[i]) s += v[i].squaredNorm();
  return std::sqrt(s);
}

}  // namespace

VSURG_SIMD_CLONES
void Multiply(const BlockMatrix& a, const std::vector<Vec3>& x, std::vector<Vec3>& y) {
  const double* blocks = a.blocks->data();
  const double* in = Data(x);
  for (int i = 0; i < a.n; ++i) {
    if (a.is_fixed[i]) {
      y[i].setZero();
      continue;
    }
    V4 acc{};
    RowSum(acc, blocks, a.col, a.row_start[i], a.row_start[i + 1], in);
    y[i] = a.c_m * a.mass[i] * x[i] + a.c_k * Three(acc);
  }
}

void BlockCg::Resize(int n) {
  for (auto* m : {&d_, &d_inverse_, &s_}) m->assign(n, Mat3::Zero());
  for (auto* v : {&r_, &z_, &p_, &q_, &t_, &u_, &w_}) v->assign(n, Vec3::Zero());
}

CgResult BlockCg::Solve(const BlockMatrix& a, Preconditioner p, const std::vector<Vec3>& b,
                        std::vector<Vec3>& x, int max_iterations, double tolerance) {
  for (int i = 0; i < a.n; ++i)
    if (a.is_fixed[i]) x[i].setZero();
  const double bnorm = FreeNorm(a, b);
  if (!(bnorm > 0)) {
    std::fill(x.begin(), x.end(), Vec3::Zero());
    return {};
  }
  Multiply(a, x, q_);
  for (int i = 0; i < a.n; ++i) r_[i] = a.is_fixed[i] ? Vec3::Zero() : Vec3(b[i] - q_[i]);
  const bool positive = Factor(a);
  if (p == Preconditioner::kGaussSeidel && positive)
    return GaussSeidel(a, x, bnorm, max_iterations, tolerance);
  return Jacobi(a, x, bnorm, max_iterations, tolerance);
}

bool BlockCg::Factor(const BlockMatrix& a) {
  bool positive = true;
  for (int i = 0; i < a.n; ++i) {
    if (a.is_fixed[i]) {
      d_[i].setZero(), d_inverse_[i].setZero(), s_[i].setZero();
      continue;
    }
    const Mat3 d = a.c_m * a.mass[i] * Mat3::Identity() + a.c_k * a.blocks[a.diag_slot[i]];
    d_[i] = d;
    d_inverse_[i] = d.inverse();
    if (!d_inverse_[i].allFinite())
      d_inverse_[i] = Mat3::Identity() / std::max(1e-12, d.trace() / 3);
    const Eigen::LLT<Mat3> llt(d);
    positive = positive && llt.info() == Eigen::Success && d_inverse_[i].allFinite();
    s_[i] = llt.matrixL();
  }
  return positive;
}

// Block-Jacobi PCG from r_ = b − A·x.
CgResult BlockCg::Jacobi(const BlockMatrix& a, std::vector<Vec3>& x, double bnorm,
                         int max_iterations, double tolerance) {
  double rz = 0;
  for (int i = 0; i < a.n; ++i) {
    z_[i] = d_inverse_[i] * r_[i];
    p_[i] = z_[i];
    rz += r_[i].dot(z_[i]);
  }
  CgResult out;
  for (; out.iterations < max_iterations; ++out.iterations) {
    out.residual = FreeNorm(a, r_) / bnorm;
    if (out.residual < tolerance) break;
    Multiply(a, p_, q_);
    double pq = 0;
    for (int i = 0; i < a.n; ++i) pq += p_[i].dot(q_[i]);
    if (!(pq > 0)) break;  // not positive definite along p (should not happen): stop
    const double alpha = rz / pq;
    double rz_new = 0;
    for (int i = 0; i < a.n; ++i) {
      x[i] += alpha * p_[i];
      r_[i] -= alpha * q_[i];
      z_[i] = d_inverse_[i] * r_[i];
      rz_new += r_[i].dot(z_[i]);
    }
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int i = 0; i < a.n; ++i) p_[i] = z_[i] + beta * p_[i];
  }
  return out;
}

// t_ = (D + Lᵀ)⁻¹·S·v, rows from the last; w_ = c_k·Lᵀ·t_ (= S·v − D·t_, the forward sweep's
// right-hand side in Â·v).
VSURG_SIMD_CLONES
void BlockCg::BackwardSweep(const BlockMatrix& a, const std::vector<Vec3>& v) {
  const double* blocks = a.blocks->data();
  const double* t = Data(t_);
  for (int i = a.n - 1; i >= 0; --i) {
    if (a.is_fixed[i]) {
      t_[i].setZero(), w_[i].setZero();
      continue;
    }
    V4 acc{};
    RowSum(acc, blocks, a.col, a.diag_slot[i] + 1, a.row_start[i + 1], t);
    const Vec3 upper = a.c_k * Three(acc);
    t_[i] = d_inverse_[i] * (s_[i] * v[i] - upper);
    w_[i] = upper;
  }
}

template <class Row>
[[gnu::always_inline]] inline void BlockCg::ForwardSweep(const BlockMatrix& a, Row&& row) {
  const double* blocks = a.blocks->data();
  const double* w = Data(w_);
  for (int i = 0; i < a.n; ++i) {
    if (a.is_fixed[i]) {
      w_[i].setZero();
    } else {
      V4 acc{};
      RowSum(acc, blocks, a.col, a.row_start[i], a.diag_slot[i], w);
      w_[i] = d_inverse_[i] * (w_[i] - a.c_k * Three(acc));
    }
    row(i);
  }
}

// out = Â·v = Sᵀ·(t + w), t and w as in the header (S is 0 on fixed rows); returns v·out.
VSURG_SIMD_CLONES
double BlockCg::ApplyHat(const BlockMatrix& a, const std::vector<Vec3>& v, std::vector<Vec3>& out) {
  BackwardSweep(a, v);
  double dot = 0;
  ForwardSweep(a, [&](int i) {
    out[i] = s_[i].transpose() * (t_[i] + w_[i]);
    dot += v[i].dot(out[i]);
  });
  return dot;
}

// ‖C·r̂‖ = ‖(D + L)·S⁻ᵀ·r̂‖ on the free vertices (the residual of A·x = b that r̂ stands for).
VSURG_SIMD_CLONES
double BlockCg::TrueResidual(const BlockMatrix& a, const std::vector<Vec3>& r_hat) {
  const double* blocks = a.blocks->data();
  const double* q = Data(u_);
  double s = 0;
  for (int i = 0; i < a.n; ++i) {
    if (a.is_fixed[i]) {
      u_[i].setZero();
      continue;
    }
    u_[i] = s_[i].transpose().triangularView<Eigen::Upper>().solve(r_hat[i]);
    V4 acc{};
    RowSum(acc, blocks, a.col, a.row_start[i], a.diag_slot[i], q);
    s += (d_[i] * u_[i] + a.c_k * Three(acc)).squaredNorm();
  }
  return std::sqrt(s);
}

// CG on Â·δ̂ = r̂₀ (the header's Eisenstat form) from r_ = b − A·x; x += C⁻ᵀ·δ̂. The stop: once
// ‖r̂‖'s fall times the last true check's ratio to it says the tolerance is met, the true
// residual decides.
CgResult BlockCg::GaussSeidel(const BlockMatrix& a, std::vector<Vec3>& x, double bnorm,
                              int max_iterations, double tolerance) {
  CgResult out;
  const double rel0 = FreeNorm(a, r_) / bnorm;
  out.residual = rel0;
  if (rel0 < tolerance) return out;
  // r̂₀ = Sᵀ·(D + L)⁻¹·r₀ into z_: the forward sweep of Â·v from w_ = r₀.
  std::copy(r_.begin(), r_.end(), w_.begin());
  double rr = 0;
  ForwardSweep(a, [&](int i) {
    z_[i] = s_[i].transpose() * w_[i];
    p_[i] = z_[i];
    r_[i].setZero();  // δ̂ from here on
    rr += z_[i].squaredNorm();
  });
  const double rr0 = rr;
  double calibration = 1;  // the true relative residual over the estimate, at the last check
  bool checked = false;
  while (out.iterations < max_iterations) {
    const double pq = ApplyHat(a, p_, q_);
    if (!(pq > 0)) break;  // not positive definite along p (should not happen): stop
    const double alpha = rr / pq;
    double rr_new = 0;
    for (int i = 0; i < a.n; ++i) {
      r_[i] += alpha * p_[i];
      z_[i] -= alpha * q_[i];
      rr_new += z_[i].squaredNorm();
    }
    ++out.iterations;
    checked = false;
    const double estimate = rel0 * std::sqrt(rr_new / rr0);
    if (calibration * estimate < tolerance) {
      out.residual = TrueResidual(a, z_) / bnorm;
      checked = true;
      if (out.residual < tolerance) break;
      calibration = out.residual / estimate;
    }
    const double beta = rr_new / rr;
    rr = rr_new;
    for (int i = 0; i < a.n; ++i) p_[i] = z_[i] + beta * p_[i];
  }
  if (!checked) out.residual = TrueResidual(a, z_) / bnorm;
  BackwardSweep(a, r_);  // δ = (D + Lᵀ)⁻¹·S·δ̂
  for (int i = 0; i < a.n; ++i) x[i] += t_[i];
  return out;
}

}  // namespace vsurg::tissue
