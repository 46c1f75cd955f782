// A finite-element membrane: the accuracy reference for the cuttable patch (CutMembrane), whose
// triangles of springs it replaces by constant-strain triangles of a Saint Venant-Kirchhoff
// material in plane stress, with the same frame, pre-strain, cuts and grasper (DESIGN.md "Cutting",
// "The patch against a membrane FEM").
//
// Kinematics (total Lagrangian). Each triangle's material (stress-free) shape is its rest-plane
// triangle shrunk by the frame's pre-strain ε (X = (1 − ε)·r), so the rim held at r stretches
// the patch by 1 / (1 − ε) in every direction, as the springs' shortened rest lengths do. With
// Dm = [X1 − X0, X2 − X0] (2×2) and Ds = [x1 − x0, x2 − x0] (3×2, the triangle in space),
// F = Ds·Dm⁻¹ (3×2), E = ½(FᵀF − I) (the Green strain, 2×2), and
//
//     S = λ*·tr(E)·I + 2μ·E,   λ* = E_Y·ν / (1 − ν²),   μ = E_Y / (2(1 + ν))   (plane stress)
//     W = t·A0·(μ·E:E + ½·λ*·tr(E)²),   ∂W/∂Ds = t·A0·F·S·Dm⁻ᵀ
//
// (A0 the material area, t the thickness). Out of its plane a flat membrane is held by its tension
// alone (the geometric term dF·S of the tangent). The tangent is exact; each element's 9×9 block
// is projected onto its positive part before assembly (a compressed triangle, which wrinkles in
// a real membrane, then adds no negative stiffness), so every Newton step goes downhill, and an
// Armijo line search on the total energy takes it.
//
// Loads: dead forces on particles (energy −f·x) and a grasper's spring toward a target
// (½k·|x − target|²), as CutMembrane::Hold. Units: m, N, Pa, J. Not thread-safe; allocates.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::tissue {

class CutMembrane;

struct MembraneFemParams {
  double thickness = 1.2e-3;       // m
  double youngs_modulus = 1.18e6;  // Pa
  // A spring lattice of equilateral triangles with Van Gelder's stiffness (CutMembrane's) answers
  // a uniform stretch as a plane-stress solid of ν = 1/3 does.
  double poisson_ratio = 1.0 / 3.0;
  double pretension = 0.02;  // the frame's pre-strain ε
};

// Checks each field by name ("poisson_ratio: must be in [0, 0.5)").
Status CheckMembraneFem(const MembraneFemParams& p);

struct MembraneMesh {
  std::vector<Eigen::Vector2d> rest;          // per vertex, the rest plane (the frame's), m
  std::vector<std::array<int32_t, 3>> faces;  // counter-clockwise in the rest plane
  std::vector<bool> fixed;                    // per vertex: held by the frame
};

// A patch as it is now: its particles (at their rest-plane positions, after snapping), its faces
// but the removed ones, and the particles on the frame held. The FEM's vertex i is particle i.
MembraneMesh MeshOf(const CutMembrane& patch);

class MembraneFem {
 public:
  // Refuses a mesh whose faces are out of range or not counter-clockwise with a positive area,
  // and bad parameters, by name. Starts flat at the rest plane (z = 0). A vertex no face uses is
  // held where it is.
  static Expected<MembraneFem> Create(const MembraneMesh& mesh, const MembraneFemParams& p);

  void SetLoad(int vertex, const geometry::Vec3& force);  // N, a dead load; zero clears it
  void Hold(int vertex, const geometry::Vec3& target, double stiffness);  // N/m; replaces the last
  void Release();

  struct Solve {
    int iterations = 0;
    double residual = 0;   // N, the largest free vertex's net force at the end
    double last_move = 0;  // m, the largest move of a vertex in the last step
    bool converged = false;
  };
  // Newton from the current positions until every free vertex's net force is below `tolerance`
  // N, or a step moved no vertex more than `move_tolerance` m. The second ends a solve whose
  // patch has slack (compressed) triangles: their folds have no stiffness in a membrane, and the
  // residual there falls only linearly while the shape no longer changes. A load that would need
  // more than `max_iterations` steps returns not converged (positions where it stopped); a
  // tangent that will not factor is an error.
  Expected<Solve> SolveStatic(double tolerance = 1e-9, int max_iterations = 100,
                              double move_tolerance = 0);
  // One Newton iteration (assembly, factorisation, solve, line search): what an implicit step of
  // this FEM costs at least; returns the residual before it, N.
  Expected<double> NewtonStep();

  double Energy() const;                       // J: the strain energy less the loads' work
  std::vector<geometry::Vec3> Forces() const;  // N: −∂Energy/∂x per vertex (0 at a held one)
  const std::vector<geometry::Vec3>& positions() const { return x_; }
  void SetPositions(const std::vector<geometry::Vec3>& x) { x_ = x; }
  int VertexCount() const { return static_cast<int>(x_.size()); }
  // The frame's tension per unit length at the rest state (N/m): t·(λ* + μ)·(s² − 1), s the
  // stretch 1 / (1 − ε); the same in every direction.
  double Tension() const;

 private:
  struct Element {
    std::array<int32_t, 3> v;
    Eigen::Matrix2d dm_inv;  // Dm⁻¹
    double volume;           // t·A0, m³
  };
  MembraneFem() = default;
  double ElementEnergy(const Element& e, const std::vector<geometry::Vec3>& x) const;
  Eigen::Matrix<double, 3, 3> ElementGradient(const Element& e) const;  // columns: ∂W/∂x_k
  Eigen::Matrix<double, 9, 9> ElementHessian(const Element& e) const;   // projected ≥ 0
  double EnergyAt(const std::vector<geometry::Vec3>& x) const;

  MembraneFemParams p_;
  double lambda_ = 0, mu_ = 0;  // λ*, μ (Pa)
  std::vector<Element> elements_;
  std::vector<geometry::Vec3> x_, load_;
  std::vector<bool> fixed_;
  std::vector<int> dof_;  // per vertex: its first free unknown, or −1 when fixed
  int held_ = -1;
  geometry::Vec3 hold_target_ = geometry::Vec3::Zero();
  double hold_k_ = 0;
  double last_move_ = 0;  // m, NewtonStep's largest vertex move
};

}  // namespace vsurg::tissue
