// Mesh deformation by the coil-spring model (DESIGN.md "Model 1", step 7).
//
// Every vertex turns about the twist axis by the twist angle at its distance ρ from the grasp:
// Φ inside the core, the linear interpolation of the boundary angles inside ring k, nothing
// beyond the cutoff radius R_P. The rotation is about the vertex's own foot point on the axis,
// so it keeps each vertex's distance to the axis exactly.
//
//   limb mode:    ρ = |s − s_grasp|, s the arc length of the vertex's closest centreline point;
//                 the axis is the centreline (its local tangent through that point).
//   surface mode: ρ = geodesic distance on the surface from the grasp point; the axis is the
//                 surface normal at the grasp point, through it.
//
// Cost. Binding (Create*) precomputes, per vertex, ρ, the offset d from the axis and q = â × d,
// and sorts vertices by ρ into groups of equal ρ (a limb's cross-sections). An update then
// evaluates one angle, one sine and one cosine per group, and x' = x + d·(cos θ − 1) + q·sin θ
// per vertex, for the groups inside R_P only; vertices that moved at the previous update and
// are now outside are put back at rest. Nothing beyond the cutoff layer is touched, and nothing
// allocates.
//
// Layout (hot data): the per-vertex rows are in ρ order, structure-of-arrays of doubles
// (d and q, 48 B/vertex, plus a 4-byte mesh index), so an update streams them front to back with
// no Eigen temporaries in the inner loop. The output is scattered into mesh order because
// positions belong to the mesh (renderers and OBJ export index them). Rejected: per-vertex
// angles with an axis–angle rotation (16× slower on the default arm, bench/coil_bench.cpp).
//
// Threads: one deformer belongs to one thread (the deformation thread); Update writes its own
// position buffer, which a reader copies or double-buffers. What binding made is one immutable
// CoilTurnTable the deformer shares (table()): a reader that needs the vertices less often than
// the model updates takes the table and a copy of the state and makes them when it needs them
// (TurnFromRest), while the deformer only evaluates the model (Evaluate).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/distances.h"
#include "common/geometry/mesh.h"
#include "common/tissue/coil_spring.h"

namespace vsurg::tissue {

enum class TwistMode { kLimb, kSurface };

struct DeformStats {
  int cutoff = 0;  // P
  bool overload = false;
  double torque = 0;         // N·m applied (clamped)
  double total_twist = 0;    // Φ, rad
  int moved_vertices = 0;    // vertices with a non-zero rotation after this update
  int touched_vertices = 0;  // vertices written by this update (moved plus put back at rest)
};

// What a binding makes, immutable afterwards. Rows in ascending ρ, x y z interleaved: the rest
// position, the offset d from the axis (⊥ axis) and axis × d, m.
struct CoilTurnTable {
  std::vector<geometry::Vec3> rest;   // mesh order
  std::vector<double> rho_by_vertex;  // ρ per vertex, m
  std::vector<double> rest_rows, d_rows, q_rows;
  // Groups of rows with equal ρ: rows [group_begin[g], group_begin[g+1]).
  std::vector<double> group_rho;
  std::vector<int32_t> group_begin;
  // Runs: rows [run_row[r], run_row[r+1]) are the vertices run_vertex[r], +1, …; group g's runs
  // are [group_run[g], group_run[g+1]).
  std::vector<int32_t> run_row, run_vertex, group_run;
  // Where each group sits among the coils, fixed at binding: θ_g = Θ_{k−1} + t·(Θ_k − Θ_{k−1})
  // (CoilSpringModel::TwistAt for a group inside the cutoff, without its per-call search).
  std::vector<int32_t> group_ring;  // k, 1..S
  std::vector<double> group_t;      // t, 0..1 (0 in the core)
  // By P = 0..S: the groups strictly inside R_P (the first groups_within[P] turn).
  std::vector<int32_t> groups_within;
};

class CoilDeformer {
 public:
  // Limb: rest positions, the centreline polyline and the grasp's arc length along it (m).
  static Expected<CoilDeformer> CreateForLimb(const CoilSpringModel& model,
                                              const std::vector<geometry::Vec3>& rest,
                                              const std::vector<geometry::Vec3>& centreline,
                                              double grasp_arc_length);
  // Limb, with the rest vertices' projections onto the centreline (ProjectOntoPolyline) made once
  // for the mesh: a new grasp then costs the binding alone, not the O(vertices × segments)
  // projection (a room or a view that binds a deformer per grasp keeps them).
  static Expected<CoilDeformer> CreateForLimb(
      const CoilSpringModel& model, const std::vector<geometry::Vec3>& rest,
      const std::vector<geometry::CentrelineProjection>& projection, double centreline_length,
      double grasp_arc_length);
  // Surface: the mesh at rest, the grasp point on it and the geodesic method.
  static Expected<CoilDeformer> CreateForSurface(const CoilSpringModel& model,
                                                 const geometry::TriMesh& rest,
                                                 const geometry::SurfacePoint& grasp,
                                                 geometry::GeodesicMethod method);

  // Deforms for a new torque (N·m, signed). Deformation thread; no allocation.
  DeformStats Update(double torque);
  // Deforms for a state already evaluated by the same model (e.g. by the haptic path).
  DeformStats Apply(const CoilState& state);
  // Evaluates the model for a new torque (N·m) and turns no vertex (touched_vertices 0,
  // moved_vertices those the state turns): state() is the new one, positions() stay as the last
  // Update or Apply left them (a reader makes the vertices from table() and state() with
  // TurnFromRest). Deformation thread; no allocation.
  DeformStats Evaluate(double torque);
  // Any thread: `out` = the table's rest mesh turned as `state` says (a state of the model the
  // table was bound with). Reuses out's capacity.
  static void TurnFromRest(const CoilTurnTable& table, const CoilState& state,
                           std::vector<geometry::Vec3>& out);

  const std::shared_ptr<const CoilTurnTable>& table() const { return table_; }
  const std::vector<geometry::Vec3>& positions() const { return deformed_; }
  const std::vector<geometry::Vec3>& rest_positions() const { return table_->rest; }
  const std::vector<double>& distances() const { return table_->rho_by_vertex; }  // ρ, m
  const CoilState& state() const { return state_; }
  TwistMode mode() const { return mode_; }
  const CoilSpringModel& model() const { return model_; }

 private:
  CoilDeformer(const CoilSpringModel& model, TwistMode mode) : model_(model), mode_(mode) {}
  // Builds the sorted rows from per-vertex ρ, foot points and axis directions.
  void Bind(const std::vector<geometry::Vec3>& rest, const std::vector<double>& rho,
            const std::vector<geometry::Vec3>& foot, const std::vector<geometry::Vec3>& axis);

  CoilSpringModel model_;
  TwistMode mode_;
  CoilState state_;
  std::shared_ptr<const CoilTurnTable> table_;
  std::vector<geometry::Vec3> deformed_;
  int moved_groups_ = 0;  // groups written with a non-zero angle by the last Update or Apply
};

}  // namespace vsurg::tissue
