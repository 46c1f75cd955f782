// A hyperelastic FEM in total-Lagrangian form: the accuracy reference for tissue beyond small
// strains, where the corotational linear model (fem.h) no longer holds (tissue stiffens as it
// stretches; the corotational model keeps large rotations but not large strains).
//
// Linear tetrahedra, the deformation gradient F = Ds·Dm⁻¹ per element (Ds, Dm the deformed and
// rest edge matrices), and a compressible energy density (per rest volume) with I1 = tr FᵀF and
// J = det F:
//   neo-Hookean (b = 0):  ψ(F) = μ/2·(I1 − 3) − μ·ln J + λ/2·(ln J)²
//   exponential (b > 0):  ψ(F) = μ/(2b)·(e^{b(I1−3)} − 1) − μ·ln J + λ/2·(ln J)²
// the second the isotropic exponential law of Demiray (J. Biomech. 1972) in Fung's exponential
// form, which stiffens as the tissue stretches and tends to the neo-Hookean one as b → 0 (both
// with the same small-strain μ, λ: Lamé's constants from Young's modulus E and Poisson's ratio ν).
// With e = e^{b(I1−3)} (1 for neo-Hookean), the first Piola–Kirchhoff stress
//   P = ∂ψ/∂F = μ·e·F − μ·F⁻ᵀ + λ·ln J·F⁻ᵀ,
// the nodal forces f_{1..3} = −V·P·Dm⁻ᵀ (columns), f_0 = −(f_1 + f_2 + f_3), and the exact tangent
//   dP = μ·e·(dF + 2b·(F:dF)·F) + (μ − λ·ln J)·F⁻ᵀ·dFᵀ·F⁻ᵀ + λ·tr(F⁻¹dF)·F⁻ᵀ
//      = μ·e·(dF + 2b·(F:dF)·F) + g''(J)·(cof F : dF)·cof F + g'(J)·d(cof F)  (g below).
// Units: m, Pa, N, J, s.
//
// Viscoelasticity (Fung's quasi-linear viscoelasticity): the second Piola–Kirchhoff stress is the
// elastic one S_e = F⁻¹·P_e convolved with a reduced relaxation function given as a Prony series,
//   S(t) = ∫ G(t − s)·dS_e/ds ds,  G(t) = g∞ + Σ g_i·e^{−t/τ_i},  g∞ = 1 − Σ g_i,
// carried by one internal stress H_i per term and element, updated exactly for S_e linear over a
// step of length h: H_i ← β_i·H_i + g_i·γ_i·ΔS_e, β_i = e^{−h/τ_i}, γ_i = (1 − β_i)/(h/τ_i). Over
// the step the stress is S = c·S_e + S_hist with c = g∞ + Σ g_i·γ_i and the history
// S_hist = Σ (β_i·H_i − g_i·γ_i·S_e,prev), which derives from the energy c·ψ + ½·S_hist:(FᵀF − I):
// each step is a static solve (Step), quasi-static unless the tissue has a density (below).
//
// Inertia (SetDensity): each step of length h is implicit (backward) Euler, taken as the minimum
// of the incremental potential
//   Φ(x) = E(x) − f·x + Σ_i m_i/(2h²)·|x_i − x̂_i|²,   x̂_i = x_i,n + h·v_i,n,
// m_i = ρ·Σ V_e/4 the vertex's lumped mass (kg); its stationarity is m·(x − x̂)/h² = f + f_int(x),
// and v_n+1 = (x_n+1 − x_n)/h. The same Newton solve and line search minimise it; it is unique
// for a step short enough, and the scheme is stable at any step and dissipates: for an E convex
// along the step, E + ½·Σ m·|v|² − f·x never rises (HyperelasticTest: a step load).
// First order in h.
//
// Near incompressibility (ν → 0.5) linear tetrahedra lock: one volume constraint per element is
// more than the nodes' motions can meet, and the mesh answers far too stiff. With `nodal_volume`
// the volumetric energy λ/2·(ln J)² is integrated at the vertices instead (the nodally averaged
// volume of Bonet & Burton, Commun. Numer. Meth. Eng. 1998, in energy form): each vertex n carries
// the rest volume V_n = Σ V_e/4 of its elements and their current volume as J_n = Σ v_e/4 / V_n,
//   E = Σ_e V_e·[ψ(F_e) less its λ term] + Σ_n V_n·λ/2·(ln J_n)²,
// so an element's stress takes the mean of its vertices' Φ'(J_n) = λ·ln J_n / J_n in place of its
// own: P = μ·e·F − μ·F⁻ᵀ + p̄·J·F⁻ᵀ, p̄ = ¼·Σ_vertices Φ'(J_n). The tangent adds, per vertex,
// V_n·Φ''(J_n)·∇J_n ∇J_nᵀ (Φ'' = λ·(1 − ln J)/J²) over its elements' vertices, and per element
// p̄·∂²v_e/∂x². One volume constraint per vertex (about a fifth of the elements' count) is what
// the motions can meet: the mesh does not lock (HyperelasticTest: Rivlin's torsion at ν = 0.499).
// A uniform deformation gives every J_n = J_e: the two forms agree there.
//
// Inversion (what Irving, Teran & Fedkiw 2004 make an element survive): ln J has no value for a
// flat or inverted element, so the volumetric terms g(J) = −μ·ln J + λ/2·(ln J)² (and λ/2·(ln J_n)²
// at the vertices) are continued below J_c = 0.1 by their second-order Taylor expansion there,
//   g(J) = g(J_c) + g'(J_c)·(J − J_c) + ½·g''(J_c)·(J − J_c)²,
// with P = μ·e·F + g'(J)·cof F (cof F = ∂J/∂F, defined for every F). Unlike Irving's clamped
// singular values, which give a force but no energy, this keeps one energy, so the Newton solve
// and its line search work through inverted states: finite, C², and g' < 0 below J_c, so the
// energy falls as an inverted element turns back. No tissue is compressed to a tenth of its
// volume, so the law is unchanged wherever it describes tissue.
//
// The static solve is Newton's method on the total potential (strain energy less the external
// forces' work) with a backtracking line search: a step is halved until the potential falls; a
// Newton direction that does not descend (the tangent indefinite far from equilibrium) is
// replaced by the steepest descent. Constraints are per coordinate: a vertex's x, y or z held at a
// value.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <array>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::tissue {

struct HyperelasticParams {
  double young = 30e3;        // Pa
  double poisson = 0.45;      // in (−1, 0.5)
  double stiffening = 0;      // b ≥ 0, dimensionless: 0 neo-Hookean, > 0 the exponential law
  bool nodal_volume = false;  // the volumetric energy at the vertices (no locking; elastic only)
};

struct PronyTerm {
  double g = 0;    // the term's share of the instantaneous stiffness, in [0, 1)
  double tau = 1;  // s
};

// The Prony terms' rules, named by field: each g ≥ 0 and τ > 0 s, both finite, and Σ g < 1.
Status CheckPronyTerms(const std::vector<PronyTerm>& terms);

// A term over a step of h s, exact for a stress (or torque) linear over the step:
// β = e^{−h/τ}, γ = (1 − β)/(h/τ) (1 as h → 0).
struct PronyDecay {
  double beta = 1, gamma = 1;
};
PronyDecay DecayOver(const PronyTerm& term, double h);

struct HyperelasticSolve {
  int iterations = 0;
  double residual = 0;  // ‖free forces‖∞ / the largest |external or reaction force| (N/N)
  bool converged = false;
};

class HyperelasticFem {
 public:
  // Refuses bad parameters and flat or inverted rest elements, naming them.
  static Expected<HyperelasticFem> Create(const geometry::TetMesh& rest, HyperelasticParams p);

  // Holds coordinate `axis` (0 x, 1 y, 2 z) of `vertex` at `value` (m) and moves it there.
  void Hold(int vertex, int axis, double value);
  void SetExternalForce(int vertex, const Eigen::Vector3d& f);  // N
  void SetPositions(const std::vector<Eigen::Vector3d>& x);     // m; a state to evaluate

  double StrainEnergy() const;  // J; finite for inverted elements too (the continued g(J))
  // −∂E/∂x, N per coordinate (3 per vertex); on held coordinates the negative reaction.
  Eigen::VectorXd InternalForces() const;
  Eigen::SparseMatrix<double> Tangent() const;  // ∂²E/∂x², N/m, symmetric

  HyperelasticSolve SolveStatic(int max_iterations = 50, double tolerance = 1e-10);

  // The relaxation's Prony terms (none: elastic); each g ≥ 0, Σ g < 1, each τ > 0, finite. Not
  // with nodal_volume (refused: the history is kept per element).
  Status SetRelaxation(std::vector<PronyTerm> terms);
  // One quasi-static step of `dt` s (the held coordinates and loads as set now): the static solve
  // with the step's stress, then the internal stresses carried forward. Elastic: SolveStatic.
  HyperelasticSolve Step(double dt, double tolerance = 1e-10);  // SolveStatic's tolerance
  // The tissue's density (kg/m³, finite, ≥ 0; 0: quasi-static, the default): each Step is then
  // implicit dynamics from the present state at rest or the last step's velocity.
  Status SetDensity(double density);
  double KineticEnergy() const;  // J, ½·Σ m_i·|v_i|²; 0 quasi-static
  // The external forces' potential, −Σ f_i·x_i (J): with the strain and kinetic energies, the
  // total a dynamic step under constant loads never raises.
  double LoadPotential() const;
  double time() const { return time_; }  // s, the steps' sum

  const std::vector<Eigen::Vector3d>& positions() const { return x_; }
  double mu() const { return mu_; }          // Pa
  double lambda() const { return lambda_; }  // Pa
  double stiffening() const { return b_; }

 private:
  struct Element {
    std::array<int, 4> v;
    Eigen::Matrix3d dm_inv;
    double volume;  // m³, at rest
  };
  HyperelasticFem() = default;
  Eigen::Matrix3d Deformation(const Element& e, const std::vector<Eigen::Vector3d>& x) const;
  double Potential(const std::vector<Eigen::Vector3d>& x) const;
  Eigen::VectorXd FreeResidual() const;  // internal + external (+ inertial) forces, 0 where held
  template <class Add>
  void ElementTangents(const std::vector<double>& pressure, Add&& add) const;
  void BuildPattern() const;
  // Newton's direction d with K·d = r (held rows an identity), K + M/h² in a dynamic step.
  Eigen::VectorXd NewtonDirection(const Eigen::SparseMatrix<double>& k, const Eigen::VectorXd& r,
                                  double target) const;
  // The solve with the relaxation carried over dt.
  HyperelasticSolve RelaxingStep(double dt, double tolerance);
  double ElementDensity(size_t e, const Eigen::Matrix3d& f) const;          // the step's, Pa
  Eigen::Matrix3d ElementStress(size_t e, const Eigen::Matrix3d& f) const;  // the step's P, Pa
  // nodal_volume: each vertex's J_n at `x` (false when an element is inverted or flat), and each
  // element's mean of its vertices' Φ'(J_n) (Pa).
  bool NodalJacobians(const std::vector<Eigen::Vector3d>& x, std::vector<double>& j) const;
  std::vector<double> ElementPressures(const std::vector<double>& j) const;
  double NodalEnergy(const std::vector<double>& j) const;  // Σ V_n·λ/2·(ln J_n)², J
  void NodalTangent(const std::vector<double>& j, std::vector<Eigen::Triplet<double>>& out) const;

  std::vector<Element> elements_;
  std::vector<Eigen::Vector3d> x_, f_ext_;
  std::vector<unsigned char> held_;  // per coordinate
  double mu_ = 0, lambda_ = 0, b_ = 0;
  // nodal_volume: each vertex's rest volume share (empty: the volumetric energy per element) and
  // its elements (node_elements_[node_start_[n] .. node_start_[n + 1]]).
  std::vector<double> node_volume_;
  std::vector<int> node_start_, node_elements_;
  // Viscoelasticity: the terms, the step's stiffness scale c and history stress per element, the
  // elastic stress at the last step's end and each term's internal stress (element-major).
  std::vector<PronyTerm> prony_;
  double scale_ = 1, time_ = 0;
  std::vector<Eigen::Matrix3d> s_hist_, s_prev_, h_;
  // Inertia: each vertex's lumped mass (empty: quasi-static), velocity and the step's predicted
  // position x̂, and 1/h² while a dynamic step is solved (0 otherwise).
  std::vector<double> mass_;
  std::vector<Eigen::Vector3d> velocity_, predicted_;
  double inertia_ = 0;
  // The elements' tangent stencil (BuildPattern, on the first Tangent without nodal_volume): the
  // pattern with zero values, and each element entry's index into its values (144 an element).
  mutable Eigen::SparseMatrix<double> pattern_;
  mutable std::vector<int> slot_;
};

}  // namespace vsurg::tissue
