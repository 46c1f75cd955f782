// A limb's twist made nonlinear: the hyperelastic FEM's (hyperelastic.h) static answers to the
// grasp turned to a few angles, stored as the load levels of a TwistTable (reduced.h), so that the
// reduced twist model carries the tissue's law (neo-Hookean or the exponential, stiffening one)
// to haptic rate at the cost of the linear field: two levels read per vertex instead of one.
//
// The load. A hand that grasps the wrist holds it: level k turns the loaded face rigidly by
// Φ_k about the axis and holds it there and at its length (every coordinate of its vertices),
// the fixed vertices at rest; the tissue settles in between. The torque of level k is the grasp's
// reaction about the axis, T_k = Σ ((x_i − o) × R_i)·â over the face (R_i = ∂E/∂x_i, the force
// the grasp exerts on the tissue there), and its axial force Σ R_i·â (the Poynting effect: a
// twisted tissue pushes on a grasp that holds its length). For a circular section the rigid face
// is what Saint-Venant's solution has anyway (its sections turn without warping), so the table's
// small-load limit is the linear field's (reduced.h, 1.), computed with the face's torque as a
// traction instead.
//
// The levels. `levels` equal steps of max_twist / levels on each side (a tissue need not answer
// both directions alike: a non-circular section or a mesh without the mirror symmetry does not),
// each solved by Newton from the last level's answer with the step spread along the axis (each
// vertex turned by the increment times its fraction of the way from the fixed end to the face);
// a level whose solve fails is approached in halved increments, at most four times.
//
// The fields of each level, per display vertex (its displacement interpolated in the FEM's
// elements by their linear shape functions, geometry::EmbedPoints): the angle it turned about the
// axis (atan2, so any angle up to π is exact), its offset's growth from the axis (radial) and its
// motion along the axis (warp); a vertex on the axis keeps its motion across it (lateral). The
// model rebuilds every vertex exactly at each level and interpolates in between. The angles are
// made continuous from level to level outward from rest (atan2 alone would read a vertex turned
// by π as −π).
//
// Cost: one sparse LDLᵀ factorisation per Newton iteration, 3–6 iterations per level (the
// forearm's 4-ring FEM, 25,344 tetrahedra, 12 levels: about 30 s, docs/BENCHMARKS.md); cached on
// disk like every reduced model (reduced_cache.h).
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/hyperelastic.h"
#include "common/tissue/reduced.h"

namespace vsurg::tissue {

struct TwistTableInputs {
  geometry::TetMesh mesh;
  HyperelasticParams material;
  std::vector<int> fixed;  // vertices held at rest
  std::vector<int> face;   // the grasped face: turned rigidly about (origin, axis) and held
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::vector<Eigen::Vector3d> display;   // the display surface's rest positions
  double max_twist = 1.5707963267948966;  // rad at the grasp, each side; in (0, π]
  int levels = 8;                         // per side, 1..32
};

struct TwistTableReport {
  int newton_iterations = 0;  // over every level
  int increments = 0;         // solves, the halved ones counted
  double worst_residual = 0;  // the largest final residual of a level (HyperelasticSolve's)
};

Expected<TwistTable> PrecomputeTwistTable(const TwistTableInputs& in,
                                          TwistTableReport* report = nullptr);

// atan2 gives each level's angles in (−π, π]: a vertex turned by about π may read −π on the
// positive side. Each level's angle is taken nearest its neighbour's toward rest (no level step
// turns a vertex by π), so the fields interpolate through the turn, not back across zero.
void ContinuousAngles(TwistTable& table);

// One solved state of the grasp turned by `twist` (rad): the FEM's positions, the torque and
// axial force the grasp holds. The reference a reduced model is rated against (the study) and the
// state each level of the table samples.
struct TwistedState {
  double twist = 0;  // rad
  std::vector<Eigen::Vector3d> positions;
  double torque = 0, axial = 0;  // N·m, N
  HyperelasticSolve solve;
};
// Solves from `from` (rest when null) in `increments` equal steps; an increment that does not
// converge is halved, at most four times (kNumerical after that).
Expected<TwistedState> SolveTwisted(const TwistTableInputs& in, double twist,
                                    const TwistedState* from = nullptr, int increments = 1,
                                    TwistTableReport* report = nullptr);

// The grasp's torque relaxing under Fung's quasi-linear viscoelasticity, carried to the torque:
// the hyperelastic FEM convolves each element's elastic stress with G(t) = g∞ + Σ g_i·e^{−t/τ_i}
// (hyperelastic.h); a reduced model convolves the elastic torque T_e(Φ) of its table with the
// same G, a few internal torques in place of a stress per element and term. Over a step of h
// with T_e linear in it, exactly as the FEM's history:
//   H_i ← β_i·H_i + g_i·γ_i·ΔT_e,  β_i = e^{−h/τ_i},  γ_i = (1 − β_i)/(h/τ_i),
//   T = c·T_e + Σ (β_i·H_i − g_i·γ_i·T_e,prev),  c = g∞ + Σ g_i·γ_i
// (T = g∞·T_e + Σ H_i after the step). Exact for the torque of a small twist; at large twists
// the FEM's stress history is carried in each element's own frame, the torque's in the grasp's
// (TwistTableTest bounds the difference). Units: N·m, s. No allocation after Create.
class TorqueRelaxation {
 public:
  static constexpr int kMaxTerms = 8;
  // The Prony terms as HyperelasticFem::SetRelaxation takes them (CheckPronyTerms), at most
  // kMaxTerms.
  static Expected<TorqueRelaxation> Create(std::vector<PronyTerm> terms);
  // One step's decay (each term's β, γ and c): computed once a step, read by every Torque of it.
  struct Step {
    std::array<PronyDecay, kMaxTerms> decay{};
    double scale = 1;  // c
  };
  Step Over(double dt) const;
  // The torque at the end of a step whose elastic torque ends at `elastic` (N·m); dT/dT_e over
  // the step is its scale. Nothing is carried.
  double Torque(double elastic, const Step& step) const;
  double Torque(double elastic, double dt) const { return Torque(elastic, Over(dt)); }
  // Carries the internal torques over the step that ended at `elastic`.
  void Commit(double elastic, const Step& step);
  void Commit(double elastic, double dt) { Commit(elastic, Over(dt)); }
  void Hold(double dt) { Commit(previous_, dt); }  // the elastic torque held for dt s
  void Reset();                                    // at rest, no history
  double relaxed_share() const;                    // g∞
  template <class A>
  void Persist(A& a) {  // common/core/state_archive.h
    a(h_, previous_);
  }

 private:
  std::vector<PronyTerm> terms_;
  std::vector<double> h_;  // N·m, one per term
  double previous_ = 0;    // the last step's elastic torque, N·m
};

}  // namespace vsurg::tissue
