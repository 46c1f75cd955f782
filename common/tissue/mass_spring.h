// Mass-spring soft tissue with spring-damper springs (the mass-spring paper §3.3, eq. 3-4 to 3-9,
// as DESIGN.md "Model 2" reads them).
//
// Particle i has mass m_i; spring s = (i, j) has stiffness k_s, damping c_s and rest length L_s.
// With l = x_j − x_i, l̂ = l/|l|:
//   force on i:  f_i = + [k_s (|l| − L_s) + c_s ((v_j − v_i)·l̂)] l̂,   f_j = −f_i      (eq. 3-5,
//   3-6)
// so a stretched spring pulls its ends together and the damper opposes the relative velocity
// along the spring (the paper's absolute value in eq. 3-6 is a typo: with it the damper would
// always push apart). m_i a_i = f_ext,i + m_i g + Σ f_i (eq. 3-4, 3-9). A spring shorter than
// 1e-12 m has no direction and exerts no force (coincident particles never give NaN).
//
// Units: m, kg, s, N; stiffness N/m, damping N·s/m.
//
// Integrators (the mass-spring paper §1 compares them and picks the midpoint method):
//   explicit-euler     x += h v;  v += h a(x, v)                                  order 1
//   symplectic-euler   v += h a(x, v);  x += h v                                  order 1
//   midpoint           RK2: a half Euler step, then the full step from the midpoint  order 2
//   rk4                classical Runge–Kutta                                      order 4
//   verlet             velocity Verlet; the damper sees an Euler-predicted end velocity  order 2
//   implicit-euler     Baraff & Witkin 1998: one Newton step of backward Euler,
//                      (M + h C + h² K) Δv = h (f + h ∂f/∂x v), by preconditioned
//                      conjugate gradient, started from Δv extrapolated from the
//                      last two steps'                                           order 1
// K is the spring stiffness matrix with the compressive transverse term clamped at zero
// (Choi & Ko 2002), so the system is symmetric positive definite and CG applies.
//
// Boundary: fixed particles never move; kinematic particles follow a position the caller sets
// for the end of each step (the pressing tool), linearly within the step, and report the force
// the tissue exerts on them.
//
// Threads: a model belongs to one thread (the deformation thread). Step() never allocates.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/simd.h"

namespace vsurg::tissue {

using geometry::Vec3;

enum class Integrator : uint8_t {
  kExplicitEuler,
  kSymplecticEuler,
  kMidpoint,
  kRk4,
  kVerlet,
  kImplicitEuler,
};
inline constexpr Integrator kAllIntegrators[] = {
    Integrator::kExplicitEuler, Integrator::kSymplecticEuler, Integrator::kMidpoint,
    Integrator::kRk4,           Integrator::kVerlet,          Integrator::kImplicitEuler};

// The command-line names: explicit-euler, symplectic-euler, midpoint, rk4, verlet, implicit-euler.
const char* IntegratorName(Integrator integrator);
Expected<Integrator> ParseIntegrator(std::string_view name);

struct Spring {
  int32_t i = 0, j = 0;
  double stiffness = 0;    // k, N/m, > 0
  double damping = 0;      // c, N·s/m, ≥ 0
  double rest_length = 0;  // L, m, ≥ 0 (zero-length springs are allowed)
};

enum class SpringKind : uint8_t { kStructural, kBending, kVolume };

// Plain data: particles and springs. Build it with the functions below or by hand.
struct MassSpringSystem {
  std::vector<Vec3> rest_positions;  // m
  std::vector<double> masses;        // kg, > 0
  std::vector<Spring> springs;
  std::vector<SpringKind> kinds;  // per spring (what built it), for reports
  int surface_particles = 0;      // the first n particles are the surface mesh's vertices
};

enum class VolumeMode : uint8_t {
  kNone,        // surface springs only (the mass-spring paper's model)
  kInnerLayer,  // a copy of the surface moved inward along the normals, joined to it
};

struct MassSpringBuildParams {
  double total_mass = 0.5;             // kg, shared equally by the particles
  double structural_stiffness = 50.0;  // N/m, springs on mesh edges
  double bending_stiffness = 5.0;  // N/m, springs across the two triangles of each edge; 0: none
  double volume_stiffness = 50.0;  // N/m, inner-layer springs
  double damping = 0.05;           // N·s/m, every spring
  VolumeMode volume = VolumeMode::kNone;
  double layer_depth = 0.01;  // m, how far inward the inner layer sits
};

// Springs on every edge, bending springs across every interior edge, and optionally an inner
// layer (its own edges, one radial spring per vertex and two shear springs per edge).
Expected<MassSpringSystem> BuildMassSpring(const geometry::TriMesh& mesh,
                                           const MassSpringBuildParams& params);
// Springs on every edge of a tetrahedral mesh (the volumetric variant); masses lumped from the
// tetrahedra's volumes at the given density (kg/m³).
Expected<MassSpringSystem> BuildMassSpring(const geometry::TetMesh& mesh, double density,
                                           double stiffness, double damping);

struct MassSpringStepParams {
  Integrator integrator = Integrator::kMidpoint;
  Vec3 gravity = Vec3::Zero();  // m/s², added to every free particle
  int cg_max_iterations = 50;   // implicit Euler
  // Relative residual of the implicit solve. 1e-3 moves the pressed sphere's contact force by
  // 0.004% against 1e-6 and needs 2.8 instead of 7.8 iterations (docs/BENCHMARKS.md).
  double cg_tolerance = 1e-3;
  // The solve also stops once its error's kinetic energy, ½ rᵀ D⁻¹ r (D the system's diagonal, the
  // preconditioner: ½ eᵀ A e for a mass-dominated A), is below this (J; 0: never). The relative
  // test alone is judged against ‖b‖, the step's net force, which vanishes as a tissue settles:
  // at rest the solve chased rounding for 20-30 iterations of every step. 1e-13 J is a 2 g
  // particle's 10 µm/s, a step's error of 10 nm.
  double cg_energy_floor = 1e-13;
  // Highest degree (1 to 3) of the extrapolation from the last steps' Δv that starts each solve;
  // each step uses the degree that would have guessed the last step's Δv best (1 is linear,
  // 2Δv₋₁ − Δv₋₂). A smooth drive at a tight tolerance takes the higher degrees: at 1e-6 the
  // arm needs 2.1 CG iterations instead of 4.1 (docs/BENCHMARKS.md).
  int cg_extrapolation = 3;
  // A step that leaves a position non-finite or farther than this from rest is a divergence.
  double divergence_distance = 1.0;  // m
};

class MassSpringModel {
 public:
  // Validates: masses finite and > 0, stiffness finite and > 0, damping finite and ≥ 0, rest
  // lengths finite and ≥ 0, indices in range and distinct, positions finite. Errors name the
  // first offending particle or spring.
  static Expected<MassSpringModel> Create(MassSpringSystem system,
                                          const MassSpringStepParams& params);

  // Boundary conditions (set-up; not during a step).
  void SetFixed(int particle, bool fixed);
  // A kinematic particle is driven by SetKinematicTarget; it starts at its current position.
  void SetKinematic(int particle, bool kinematic);
  // Position the kinematic particle reaches at the end of the next step (m).
  void SetKinematicTarget(int particle, const Vec3& target);
  void SetExternalForce(int particle, const Vec3& force);  // N, held until changed
  void ClearExternalForces();
  // A zero-length spring-damper from a particle to a fixed point (N/m, N·s/m): how a tool
  // couples to the tissue. Unlike an external force it is part of the implicit solve, so a
  // coupling stiffer than the tissue stays stable. Held until ClearAnchors; at most 64 (more are
  // ignored).
  void SetAnchor(int particle, const Vec3& target, double stiffness, double damping);
  void ClearAnchors();
  void SetIntegrator(Integrator integrator);

  // Topology changes (a cut: tissue/cut_membrane.h, mass_spring_topology.cpp). Set-up: room for
  // `capacity` particles in all, so that SplitParticle never allocates.
  void ReserveParticles(int capacity);
  // A new particle, a copy of particle `of` (its rest and current position, velocity and role;
  // no external force), of `mass` kg (> 0): a cut separates a node into copies, one per side.
  // Returns its index, or -1 when the reserved room is full or the mass is not > 0. The
  // implicit solve's warm start begins afresh. Never allocates within the reserved room.
  int SplitParticle(int of, double mass);
  void SetMass(int particle, double mass);  // kg, finite and > 0; else ignored
  // Spring s's ends and rest length (m): a cut moves a spring from a node to its copy, and
  // node snapping changes the rest lengths around a moved node. Ignored when out of range.
  void SetSpring(size_t s, int i, int j, double rest_length);
  void SetRestPosition(int particle, const Vec3& rest);  // m; finite

  // Advances by dt seconds in `substeps` equal steps. Returns false, leaves the state at rest
  // and sets diverged() when the motion diverged (non-finite or beyond divergence_distance).
  bool Step(double dt, int substeps = 1);
  // Back to rest: positions at rest, velocities zero, divergence flag cleared.
  void Reset();
  // Every particle's position (m) and velocity (m/s), as from positions() and velocities() (live
  // migration): sizes must match and values be finite, positions within divergence_distance of
  // rest. The solver's warm start begins afresh, as after Reset.
  Status SetState(const std::vector<Vec3>& x, const std::vector<Vec3>& v);

  const std::vector<Vec3>& positions() const { return x_; }
  const std::vector<Vec3>& velocities() const { return v_; }
  const MassSpringSystem& system() const { return sys_; }
  bool diverged() const { return diverged_; }
  int last_cg_iterations() const { return cg_iterations_; }
  // The degree of the extrapolation that started the last implicit solve (1 to 3).
  int last_extrapolation() const { return last_extrapolation_; }

  double KineticEnergy() const;    // J, ½ Σ m v²
  double PotentialEnergy() const;  // J, ½ Σ k (|l| − L)² (+ gravity: −Σ m g·x)
  double MaxDisplacement() const;  // m, max |x − x_rest|
  // The force the springs and dampers exert on particle i (N): on a kinematic particle, the
  // reaction the driving tool feels is its negative.
  Vec3 InternalForceOn(int particle) const;
  // Largest ω = sqrt(λ_max(M⁻¹K)) at rest (rad/s), by power iteration: the explicit step limit
  // is 2/ω (symplectic Euler) and 2√2/ω (RK4).
  double MaxAngularFrequency(int iterations = 200) const;

 private:
  enum class Role : uint8_t { kFree, kFixed, kKinematic };

  MassSpringModel() = default;
  // a = M⁻¹ f(x, v) for free particles, 0 for the others.
  void Accelerations(const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                     std::vector<Vec3>& a) const;
  void Forces(const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::vector<Vec3>& f) const;
  // Kinematic particles at fraction `alpha` of the current step.
  void PlaceKinematic(std::vector<Vec3>& x, std::vector<Vec3>& v, double alpha, double h) const;
  // One step of h; false when it left a particle beyond divergence_distance or a velocity not
  // finite (CheckFinite).
  bool StepOnce(double h);
  bool CheckFinite() const;
  // Springs shorter than this (m) have no direction and exert no force.
  static constexpr double kMinLength = 1e-12;

  // Implicit Euler (mass_spring_implicit.cpp): the step, and its stages in order.
  bool StepImplicit(double h);
  void ImplicitGuess(double h, bool refresh_diag);           // Δv₀; the particles' terms
  void ImplicitSprings(double h, bool refresh_diag);         // the springs' terms
  void ImplicitPreconditioner(double h, bool refresh_diag);  // the anchors; the filter
  int ImplicitSolve(double h);                               // CG; returns its iterations
  double ImplicitProduct(double h, bool next, double beta);  // q = A p, returns pᵀA p
  bool ImplicitUpdate(double h);                             // x₁, v₁; false when diverged

  MassSpringSystem sys_;
  MassSpringStepParams params_;
  std::vector<Role> role_;
  std::vector<double> inv_mass_;
  std::vector<Vec3> x_, v_, f_ext_;
  std::vector<Vec3> kin_start_, kin_target_;
  std::vector<int> kinematic_;  // indices of kinematic particles
  struct Anchor {
    int i;
    Vec3 target;
    double k, c;
  };
  static constexpr size_t kMaxAnchors = 64;
  std::vector<Anchor> anchors_;  // capacity reserved at Create
  bool diverged_ = false;
  int cg_iterations_ = 0;
  bool verlet_primed_ = false;

  // Scratch, sized once at Create: no allocation per step.
  std::vector<Vec3> a_, tx_, tv_, k1v_, k2x_, k2v_, k3x_, k3v_, kin_final_;
  // Implicit Euler: per spring s, arrays the springs' pass (ImplicitSprings) streams and the
  // compiler vectorises over: the ends, the block B_s = a l̂l̂ᵀ + b I of h C_s + h² K_s as l̂ (padded
  // to four doubles, one AVX register) and the scalars a and b, and the spring's L, k and c. The CG
  // product reads ends, l̂, a and b (56 bytes a spring: 344 KB for the 6144 springs of the
  // 1026-particle sphere, inside L2). The alternatives measured (a record per spring, a gather per
  // particle) are in docs/BENCHMARKS.md, "The implicit step in five stages".
  struct SpringEnds {
    int32_t i, j;
  };
  // Only the springs with a free end are in these arrays: a spring between two fixed or driven
  // particles adds only to rows the solve filters to zero, so it costs nothing (the sphere's
  // fixed base: a fifth of its springs). Rebuilt from sys_.springs, within the capacity
  // reserved at Create, when a particle's role changes.
  std::vector<SpringEnds> ends_;
  bool solver_springs_stale_ = true;
  void SelectSolverSprings();
  std::vector<simd::Lane4> dirs_;
  std::vector<double> coef_a_, coef_b_, rest_, stiffness_, damping_;
  std::vector<int> constrained_;  // fixed and kinematic particles: Δv = 0 in the solve
  // The solver's per-particle vectors: 4 doubles per particle (x, y, z, 0), 32-byte aligned.
  std::vector<simd::Lane4> dv_, r_, p_, q_, precond_, pos_;
  // pos_ and state_'s first halves hold the free particles' x and v (ImplicitUpdate).
  bool lanes_ = false;
  // diag(M + h C + h² K) of the springs (no anchors), summed by the springs' pass only every
  // kDiagEvery steps and when h or the solver's springs change; in between the preconditioner
  // starts from it (diag_age_ steps old, diag_h_ the h it was summed for).
  static constexpr int kDiagEvery = 8;
  std::vector<simd::Lane4> diag_, inv_diag_;  // and its reciprocal (the preconditioner)
  int diag_age_ = kDiagEvery;
  double diag_h_ = 0;
  // The last four steps' Δv (history_[h_] the newest; the buffers rotate instead of being
  // copied) for the solve's first guess: the polynomial extrapolation of degree
  // extrapolation_ (1 to 3, at most params_.cg_extrapolation) whose guess for the last step's Δv
  // was closest.
  std::array<std::vector<simd::Lane4>, 4> history_;
  int h_ = 0;
  int extrapolation_ = 1, last_extrapolation_ = 1;
  static constexpr int kJudgeEvery = 4;
  int judge_age_ = kJudgeEvery - 1;  // the first step compares
  // The guess's and the springs' per-particle pairs: (v₀, Δv₀) it reads and (rhs, −A Δv₀) it sums,
  // so one load and one sum per spring end serve both.
  std::vector<simd::Lane8> state_, sums_;
};

}  // namespace vsurg::tissue
