// The FEM's step matrix and the conjugate gradients that solve it (common/tissue/fem.h,
// DESIGN.md "Model 3").
//
//   A = c_m·M + c_k·K,  M lumped (a mass per vertex), K symmetric in a block CSR of 3×3 blocks,
//
// with the fixed vertices' rows and columns left out (their entries of every vector are 0).
// Write A = L + D + Lᵀ with D its 3×3 diagonal blocks and L the blocks below them. Two
// preconditioners:
//
//  - block Jacobi, P = D: cheap, and the iterations grow as the tolerance tightens;
//  - symmetric block Gauss–Seidel, P = (D + L)·D⁻¹·(D + Lᵀ) = C·Cᵀ with C = (D + L)·S⁻ᵀ and
//    D_i = S_i·S_iᵀ (Cholesky). CG runs on Â = C⁻¹·A·C⁻ᵀ in Eisenstat's form (Eisenstat, SIAM J.
//    Sci. Stat. Comput. 2, 1981): since A = (D + L) + (D + Lᵀ) − D,
//
//      (D + L)⁻¹·A·(D + Lᵀ)⁻¹ = (D + Lᵀ)⁻¹ + (D + L)⁻¹·(I − D·(D + Lᵀ)⁻¹),
//
//    so Â·v = Sᵀ·(t + w) with u = S·v, t = (D + Lᵀ)⁻¹·u (a backward sweep) and
//    w = (D + L)⁻¹·(u − D·t) (a forward sweep): the two sweeps read each off-diagonal block once,
//    as one product A·v does, and no separate product is needed. CG solves A·δ = r₀ for the
//    correction to the first guess x₀: r̂₀ = C⁻¹·r₀ = Sᵀ·(D + L)⁻¹·r₀, δ = C⁻ᵀ·δ̂ = (D + Lᵀ)⁻¹·S·δ̂.
//    The stop is on the true relative residual ‖b − A·x‖/‖b‖ (r = C·r̂, half a product), checked
//    once ‖r̂‖'s fall says it should be met, so both preconditioners stop at the same tolerance.
//
// Threads: a solver belongs to one thread; nothing allocates after Resize.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace vsurg::tissue {

struct BlockMatrix {
  int n = 0;  // vertices
  double c_m = 0, c_k = 0;
  const int* row_start = nullptr;           // row r's blocks are [row_start[r], row_start[r + 1])
  const int* col = nullptr;                 // sorted within each row
  const int* diag_slot = nullptr;           // the slot of (r, r)
  const Eigen::Matrix3d* blocks = nullptr;  // K, with one block of padding past the last
  const double* mass = nullptr;             // kg per vertex
  const uint8_t* is_fixed = nullptr;
};

// y = A·x on the free vertices; the fixed rows 0.
void Multiply(const BlockMatrix& a, const std::vector<Eigen::Vector3d>& x,
              std::vector<Eigen::Vector3d>& y);

enum class Preconditioner { kBlockJacobi, kGaussSeidel };

struct CgResult {
  int iterations = 0;
  double residual = 0;  // ‖b − A·x‖/‖b‖ on the free vertices
};

class BlockCg {
 public:
  void Resize(int n);
  // A·x = b from the first guess x to `tolerance` (relative), or `max_iterations`. A diagonal
  // block that is not positive definite (it cannot be for a mass > 0 and K ⪰ 0) makes the
  // Gauss–Seidel solve fall back to block Jacobi.
  CgResult Solve(const BlockMatrix& a, Preconditioner p, const std::vector<Eigen::Vector3d>& b,
                 std::vector<Eigen::Vector3d>& x, int max_iterations, double tolerance);

 private:
  using Vec3 = Eigen::Vector3d;
  using Mat3 = Eigen::Matrix3d;
  bool Factor(const BlockMatrix& a);  // d_, d_inverse_, s_; false: a block not positive definite
  CgResult Jacobi(const BlockMatrix& a, std::vector<Vec3>& x, double bnorm, int max_iterations,
                  double tolerance);
  CgResult GaussSeidel(const BlockMatrix& a, std::vector<Vec3>& x, double bnorm, int max_iterations,
                       double tolerance);
  double ApplyHat(const BlockMatrix& a, const std::vector<Vec3>& v, std::vector<Vec3>& out);
  void BackwardSweep(const BlockMatrix& a, const std::vector<Vec3>& v);  // t_ = (D + Lᵀ)⁻¹·S·v
  // w_ ← (D + L)⁻¹·w_ in place (fixed rows 0), calling row(i) as soon as row i is done.
  template <class Row>
  void ForwardSweep(const BlockMatrix& a, Row&& row);
  double TrueResidual(const BlockMatrix& a, const std::vector<Vec3>& r_hat);  // ‖C·r̂‖

  std::vector<Mat3> d_, d_inverse_, s_;
  std::vector<Vec3> r_, z_, p_, q_, t_, u_, w_;
};

}  // namespace vsurg::tissue
