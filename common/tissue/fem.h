// The FEM reference (DESIGN.md "Model 3"): linear tetrahedra, corotational (large rotations),
// lumped mass, Rayleigh damping; implicit Euler with a warm-started conjugate gradient, and a
// static equilibrium solve with a sparse Cholesky factorisation.
//
// Legend (SI): X rest positions (m), x current, v velocities (m/s), M lumped mass (kg), K
// stiffness (N/m), D = α·M + β·K Rayleigh damping, h step (s), f_ext external forces (N).
//
// Element e with vertices 0..3 (Müller & Gross 2004, "Interactive virtual materials"):
//   shape gradients g_a from the rest edge matrix, V rest volume, Lamé λ, μ from E, ν (E times
//   the element's own scale in a heterogeneous tissue);
//   K_ab = V·(λ·g_a g_bᵀ + μ·g_b g_aᵀ + μ·(g_a·g_b)·I)            (3×3 block of the 12×12 Ke)
//   R = the rotation of the deformation gradient F = D_s·D_m⁻¹, by Newton's iteration on
//       tr(Rᵀ F) warm-started from the previous step, falling back to the iteration of Müller et
//       al. 2016 ("A robust method to extract the rotational part of deformations") where
//       Newton's matrix is not positive definite: it always returns a rotation, also for a flat
//       or inverted element (where a polar decomposition's R would be a reflection or
//       undefined), so an inverted element is pushed back instead of producing NaN.
//   f_a = −R·Σ_b K_ab·(Rᵀ x_b − X_b),   stiffness blocks R·K_ab·Rᵀ.
//
// Implicit Euler, linearised (one Newton step, Baraff & Witkin 1998):
//   (M + h·D + h²·K)·Δv = h·(f(x) + f_ext − D·v − h·K·v),  v ← v + Δv,  x ← x + h·v.
// The matrix is assembled each step into a block-CSR of 3×3 blocks whose pattern and element →
// slot map are precomputed, then solved by CG preconditioned by symmetric block Gauss–Seidel in
// Eisenstat's form (block_cg.h; block Jacobi on request) started from Δv extrapolated from the
// last steps'. Fixed vertices are Dirichlet: their rows are projected out
// of the CG.
//
// Static: K(x)·Δx = f(x) + f_ext, repeated (corotated quasi-Newton) until the residual is below
// tolerance; Eigen's SimplicialLDLT under a nested-dissection ordering (METIS) with the pattern
// analysed once, the factorisation kept while it still cuts the residual tenfold per iteration.
//
// Threads: a model belongs to one thread; nothing here allocates after Create except SolveStatic.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/block_cg.h"

namespace vsurg::tissue {

struct FemParams {
  double young = 34800;   // Pa (G = 12 kPa with ν = 0.45, DESIGN.md default tissue)
  double poisson = 0.45;  // < 0.5
  double density = 1050;  // kg/m³
  // Per tetrahedron, the factor its Young's modulus is multiplied by (a heterogeneous tissue:
  // inclusions.h); empty is homogeneous. Each > 0 and finite, one per element.
  std::vector<double> element_stiffness_scale;
  // Rayleigh D = α·M + β·K. The defaults damp a forearm's first torsion mode (≈ 20 rad/s) at
  // ζ ≈ α/(2ω) ≈ 0.12 and leave β small: β·h·ω_max² would dominate the step matrix and slow CG.
  double mass_damping = 5.0;         // α, 1/s
  double stiffness_damping = 0.001;  // β, s
  bool corotational = true;          // false: small-strain linear FEM (R = I)
  // The λ term of the energy integrated at the vertices instead of per element (a static
  // response's K₀ only; FemModel refuses it): vertex n carries V_n = Σ V_e/4 and the volume
  // strain θ_n = Σ_e (V_e/4)·div u_e / V_n, the energy Σ_n ½·Λ_n·V_n·θ_n² with Λ_n the volume-
  // weighted λ of its elements. One volume constraint per vertex instead of per element: linear
  // tetrahedra no longer lock as ν → 0.5 (the hyperelastic reference's nodal_volume at small
  // strain; DESIGN.md "The FEM against Hertz's contact").
  bool nodal_volume = false;
  int max_cg_iterations = 400;
  // Symmetric block Gauss–Seidel: 0.4× block Jacobi's iterations at about the same cost each
  // (docs/BENCHMARKS.md, the FEM step against VegaFEM's).
  Preconditioner preconditioner = Preconditioner::kGaussSeidel;
  double cg_tolerance = 1e-4;  // relative residual ‖r‖/‖b‖ of each step's Δv
  // Highest degree (1 to 3) of the extrapolation from the last steps' Δv that starts each
  // step's CG; each step takes the degree that guessed the last step best (extrapolation.h).
  int cg_extrapolation = 3;
};

struct FemStepStats {
  int cg_iterations = 0;
  double residual = 0;  // relative
  bool converged = false;
  int inverted = 0;       // elements with det F ≤ 0 at the start of the step
  int extrapolation = 1;  // the degree of Δv's first guess (1 to 3)
};

struct FemStaticStats {
  int iterations = 0;
  double residual = 0;  // ‖f + f_ext‖ on free vertices / ‖f_ext‖
  bool converged = false;
};

class FemModel {
 public:
  // `fixed`: Dirichlet vertices (held at their rest positions). Elements of volume ≤ 1e-15 m³
  // (flat or inverted in the rest mesh) are rejected naming the element.
  static Expected<FemModel> Create(const geometry::TetMesh& mesh, const FemParams& params,
                                   const std::vector<int>& fixed);
  FemModel(FemModel&&) noexcept;
  FemModel& operator=(FemModel&&) noexcept;
  ~FemModel();

  void SetExternalForce(int vertex, const Eigen::Vector3d& f);  // N
  void ClearExternalForces();
  FemStepStats StepImplicit(double h);
  FemStaticStats SolveStatic(int max_iterations = 20, double tolerance = 1e-8);
  // Moves a vertex (tests: invert an element on purpose); velocity untouched.
  void SetPosition(int vertex, const Eigen::Vector3d& x);
  void Reset();  // back to rest, at rest

  const std::vector<Eigen::Vector3d>& positions() const;
  const std::vector<Eigen::Vector3d>& velocities() const;
  const geometry::TetMesh& rest() const;
  double KineticEnergy() const;  // J
  double ElasticEnergy() const;  // J, corotated linear
  int TetCount() const;
  int VertexCount() const;
  int InvertedCount() const;  // elements with det F ≤ 0 now

 private:
  struct Impl;
  friend class FemStaticResponse;
  explicit FemModel(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The small-strain (rest) stiffness K₀ of a FemModel's mesh, factorised once with a sparse
// Cholesky (Eigen's SimplicialLDLT, FillOrdering) and solved for as many static loads as asked: u =
// K₀⁻¹·f on the free vertices, the fixed ones held. The precomputation of the reduced models
// (common/tissue/reduced.h): each of their responses is one back-substitution. Linear in f, so
// a response to a unit load scales to any load; it is the corotational FEM's tangent at rest,
// which a small load's SolveStatic matches to its tolerance.
// The fill-reducing ordering of the factorisation: nested dissection (METIS; the default: on the
// organ's 20-cell ball it fills less and factorises and solves faster, docs/BENCHMARKS.md) or
// Eigen's approximate minimum degree (what the tables used before; kept for that comparison).
enum class FillOrdering { kNestedDissection, kMinimumDegree };

class FemStaticResponse {
 public:
  static Expected<FemStaticResponse> Create(
      const geometry::TetMesh& mesh, const FemParams& params, const std::vector<int>& fixed,
      FillOrdering ordering = FillOrdering::kNestedDissection);
  FemStaticResponse(FemStaticResponse&&) noexcept;
  FemStaticResponse& operator=(FemStaticResponse&&) noexcept;
  ~FemStaticResponse();

  // Displacements (m) of every vertex under nodal loads (N) `f` (one per vertex; the fixed
  // vertices' entries are ignored and their displacement is zero).
  std::vector<Eigen::Vector3d> Solve(const std::vector<Eigen::Vector3d>& f) const;
  // Solve for many loads at once, the same answers to the last bit: the factor is streamed
  // through memory once per eight loads (the solve is bound by reading it) and the blocks are
  // spread over up to `threads` threads (0: one per core, at most four). The reduced models'
  // tables are hundreds of loads on one factor.
  std::vector<std::vector<Eigen::Vector3d>> SolveMany(
      const std::vector<std::vector<Eigen::Vector3d>>& f, int threads = 0) const;
  int VertexCount() const;
  const geometry::TetMesh& rest() const;

 private:
  struct Impl;
  explicit FemStaticResponse(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Nodal forces on `face_vertices` (a cross-section normal to `axis` through `centre`) with
// moment `torque` (N·m) about the axis: the linear shear traction of Saint-Venant torsion,
// τ = T·r/J, lumped with each vertex's face area `area` (m²):
//   f_i = T·A_i·(axis × r_i) / Σ_j A_j·|r_j|².
// Σ r_i × f_i = T·axis exactly; the resultant is zero when the face is symmetric.
std::vector<Eigen::Vector3d> TorqueNodalForces(const std::vector<Eigen::Vector3d>& positions,
                                               const std::vector<int>& face_vertices,
                                               const std::vector<double>& area,
                                               const Eigen::Vector3d& centre,
                                               const Eigen::Vector3d& axis, double torque);

}  // namespace vsurg::tissue
