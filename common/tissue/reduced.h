// Reduced models precomputed from the scene's own FEM (DESIGN.md "Model 3"): FEM accuracy at
// haptic rate. Each is a linear response of the FEM at rest, computed once per scene by
// FemStaticResponse (one sparse Cholesky factorisation, one back-substitution per response),
// carried onto the display surface the station draws (geometry::EmbedPoints: the FEM's own
// linear shape functions), and evaluated at run time as a few multiply-adds per vertex.
//
// Units: m, N, N·m, rad. Precision: the responses are kept in single precision (the display is
// in float anyway; 7 digits is far below the FEM's discretisation error of 2–5%).
//
// 1. Twist field (torsion of limbs). Saint-Venant torsion is linear in the torque T: every
//    point turns by T·a(x) about the axis and moves T·w(x) along it (the warping of a
//    non-circular section). So one static FEM solve at a unit torque (the shear traction of
//    TorqueNodalForces on the loaded face) gives a(x) = (â × r)·u / |r|² and w(x) = â·u per
//    display vertex, and the radial part q(x) = r·u / |r|² (zero in Saint-Venant; the FEM's
//    end effects near the loaded face), so that at a small torque the model is the FEM's
//    response exactly. An update at torque T scales r by 1 + T·q, turns it by T·a about the
//    axis and moves the vertex T·w along it (a vertex on the axis, where no angle is defined,
//    moves by T·u⊥ instead): exact
//    rotations, so a large twist keeps every vertex's distance to the axis (a linear
//    displacement T·u would inflate the limb by 1/cos θ). The grasp's compliance a_g (rad per
//    N·m, the loaded face's mean angle) gives the haptic path its stiffness dT/dΦ = 1/a_g.
//    Choi & Ko's modal warping (IEEE TVCG 2005) is the route for loads that are not a pure
//    twist; a limb twisted at the grasp is one.
//
// 2. Contact responses (palpation, pressing, pulling): Green's functions (Cotin, Delingette &
//    Ayache, IEEE TVCG 1999). For every display vertex a tool can reach, the static response of
//    every display vertex to a unit force in x, y and z spread over the tool's footprint (a disc
//    of the tool's radius on the FEM's boundary, lumped by area like a pressure): 9 floats per
//    (contact, vertex) pair. A press with force F at contact c moves vertex i by G_ic·F;
//    several contacts superpose. A tool that imposes a position instead (the haptic proxy)
//    gets the force from the contact's own 3×3 block: F = G_cc⁻¹·δ, the capacitance matrix of
//    James & Pai (1999) for one contact, and that inverse is also the stiffness the station's
//    local model needs. Memory: 36 B × reachable contacts × display vertices (1,026-vertex
//    sphere, every vertex reachable: 37.9 MB), twice that with the rotation correction;
//    `Create` refuses more than max_bytes.
//
// 3. Rotation correction of the contact responses (the static form of modal warping, Choi & Ko,
//    IEEE TVCG 11(1) 2005, eq. 9–11). A linear response moves every point along a straight
//    line, so material that turns (the surface tilting into a deep press) is stretched: a
//    rotation by θ moves a point at distance r by r·θ instead of 2r·sin(θ/2) and lengthens it to
//    r·√(1+θ²), inflating the volume. Beside each displacement response the table keeps the
//    linearised rotation it carries, w = ½∇×u (the FEM's element gradients, volume-averaged at
//    its vertices, interpolated like u), so a press gives per vertex u = G·F and w = Ψ·F, and
//    the vertex moves by ũ = R̃(w)·u, the displacement integrated in a frame that turns
//    uniformly from 0 to w:
//      R̃(w) = ∫₀¹ R(s·w) ds = I + A(θ)·[w]× + B(θ)·[w]×²,  θ = |w|,
//      A = (1 − cos θ)/θ², B = (θ − sin θ)/θ³.
//    For a rigid turn (u = w × r) this is exactly (R(w) − I)·r: lengths are kept. The
//    correction is second order in the load, so a small press is the FEM's linear response
//    still; θ is held at ≤ π/2 (no press turns the surface further). It is the corotational
//    law's answer: against a hyperelastic ball pressed 15 mm it does worse than the responses
//    alone, at five times the cost (ContactResponseParams::rotation; a scene's "rotation").
//
// 4. Surface twist (forceps grasping an organ's surface and twisting it about the normal there).
//    The twist field of 1. for every display vertex a tool can grasp: the FEM's response to a
//    unit torque about the vertex's outward normal, carried by the shear traction of
//    TorqueNodalForces on the jaws' disc (the FEM's boundary within jaw_radius, at least its four
//    nearest vertices), 12 B per (grasp, vertex) pair (angle, warp, radial; 1,026-vertex sphere,
//    865 grasps: 10.6 MB). A grasp takes its vertex's field (or the nearest precomputed one's,
//    flagged) into a ReducedTwistModel: exact rotations about that normal, the held organ turning
//    as a whole where the coil model's cutoff layer would stop the twist.
//
// Hard cases: a non-finite torque, force or displacement is refused (the positions keep the
// last good state, the result says so); a torque or force past the model's capacity is clamped
// to it and flagged (`saturated`); a contact at a vertex never precomputed uses the nearest
// precomputed one and is flagged (`fallback`). Positions are always finite.
//
// Threads: a model belongs to one thread; Update/Press do not allocate.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/fem.h"

namespace vsurg::tissue {

// ---- 1. Twist field ---------------------------------------------------------------------------

struct TwistField {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // a point on the twist axis, m
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();   // unit
  std::vector<float> angle;                          // rad per N·m, per display vertex
  std::vector<float> warp;                           // m per N·m along the axis, per vertex
  std::vector<float> radial;                         // 1 per N·m: radial strain, per vertex
  std::vector<Eigen::Vector3d> lateral;  // m per N·m ⊥ axis, for vertices on the axis only
  double grasp_compliance = 0;           // rad per N·m at the loaded face
  double max_distance = 0;               // m: the display vertex farthest outside the FEM mesh
};

// The FEM's static response to a unit torque about (origin, axis) on `face` (vertex indices of
// the FEM mesh with their areas, m²: TorqueNodalForces), sampled at `display_rest`.
Expected<TwistField> PrecomputeTwistField(const FemStaticResponse& fem,
                                          const std::vector<int>& face,
                                          const std::vector<double>& face_area,
                                          const Eigen::Vector3d& origin,
                                          const Eigen::Vector3d& axis,
                                          const std::vector<Eigen::Vector3d>& display_rest);

struct ReducedStats {
  bool ok = true;          // false: the input was not finite; nothing changed
  bool saturated = false;  // the load was clamped to the model's capacity
  bool fallback = false;   // the contact vertex was not precomputed; the nearest one was used
  double load = 0;         // torque (N·m) or force magnitude (N) actually applied
};

// The rotation correction's operator R̃(w)·u (reduced.h, 3.) for one vertex, in double: the
// reference the vectorised loop is tested against. w in rad (held at |w| ≤ π/2), u in m.
Eigen::Vector3d WarpedDisplacement(const Eigen::Vector3d& w, const Eigen::Vector3d& u);

// A twist at several load levels (the nonlinear table, common/tissue/twist_table.h, or a linear
// field as three levels): level k is the state of the grasp turned by twist[k] (rad) and held by
// torque[k] (N·m), both strictly rising, one level at rest (0, 0); its fields are absolute, per
// display vertex: angle (rad) about the axis, warp (m) along it, radial (1: the offset from the
// axis grown by 1 + radial), lateral (m ⊥ the axis, for vertices on the axis only). Between two
// levels a vertex takes the fields interpolated linearly in the torque; past the end levels the
// end segments are extended (the linear field's is its whole law).
struct TwistTable {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::vector<double> twist, torque;  // per level: rad at the grasp, N·m
  std::vector<double> axial;          // per level: N along the axis the grasp holds (Poynting)
  int vertices = 0;
  std::vector<float> angle, warp, radial;  // [level·vertices + i]
  std::vector<Eigen::Vector3d> lateral;    // [level·vertices + i]
  double max_distance = 0;                 // m: the display vertex farthest outside the FEM mesh
  int Levels() const { return static_cast<int>(twist.size()); }
};

// The linear field as a table: levels at −1, 0 and 1 N·m, the grasp at ∓/± its compliance.
TwistTable LinearTwistTable(const TwistField& field);
// Sizes, finiteness, a unit axis, a level at rest and both curves strictly rising (a table read
// from disk is checked before use).
Status ValidateTwistTable(const TwistTable& table, size_t display_vertices);

class ReducedTwistModel {
 public:
  // `max_twist`: the largest angle any vertex may turn (rad, ≤ π); the torque capacity on each
  // side follows from the table (the torque at which its largest vertex angle reaches max_twist;
  // for a linear field max_twist / max |a|).
  static Expected<ReducedTwistModel> Create(const TwistField& field,
                                            const std::vector<Eigen::Vector3d>& display_rest,
                                            double max_twist);
  static Expected<ReducedTwistModel> Create(const TwistTable& table,
                                            const std::vector<Eigen::Vector3d>& display_rest,
                                            double max_twist);
  ReducedStats Update(double torque);  // N·m; no allocation
  const std::vector<Eigen::Vector3d>& positions() const { return positions_; }
  // N·m: the smaller of the two sides' capacities (equal for a linear field).
  double torque_capacity() const { return std::min(capacity_lo_, capacity_hi_); }
  double grasp_stiffness() const;           // N·m/rad, dT/dΦ at rest
  double grasp_twist(double torque) const;  // rad at the grasp for a torque
  // The torque the tissue holds at a twist Φ of the grasp (rad), dT/dΦ there, and whether Φ is
  // past the capacity (the torque then clamped to it, the stiffness 0). No allocation.
  struct Answer {
    double torque = 0, stiffness = 0;
    bool overload = false;
  };
  Answer TorqueAt(double twist) const;
  int VertexCount() const { return static_cast<int>(positions_.size()); }
  int Levels() const { return static_cast<int>(level_torque_.size()); }

 private:
  ReducedTwistModel() = default;
  // The segment [k, k+1] of the levels' `curve` that holds x (the end ones extended).
  int Segment(const std::vector<double>& curve, double x) const;
  Eigen::Vector3d origin_, e1_, e2_, axis_;
  int nv_ = 0;
  // Per vertex (structure of arrays, float): the rest offset from the axis in its frame (r1,
  // r2); per level and vertex ([level·nv + i]) the fields (angle, warp, radial, lateral l1, l2);
  // rest and output positions in double.
  std::vector<float> r1_, r2_, angle_, warp_, radial_, l1_, l2_;
  std::vector<double> level_twist_, level_torque_;
  int rest_level_ = 0;
  std::vector<Eigen::Vector3d> rest_, positions_;
  std::vector<float> dx_, dy_, dz_;           // scratch: the displacement in the axis frame
  double capacity_lo_ = 0, capacity_hi_ = 0;  // N·m, each side's (both > 0)
};

// ---- 2. Contact responses ---------------------------------------------------------------------

struct ContactResponseParams {
  double footprint_radius = 0.005;  // m: the tool tip's contact disc
  int64_t max_bytes = 256ll << 20;  // refuse a table larger than this
  bool rotation = true;             // keep the rotation responses (3.): twice the memory
};

struct ContactResponse {
  int vertices = 0;                  // display vertices
  std::vector<int> contacts;         // the precomputed contact vertices (display indices)
  std::vector<int> slot_of_vertex;   // display vertex → its contact slot, or the nearest slot
  std::vector<uint8_t> precomputed;  // display vertex → 1 when it has its own slot
  // g[((slot·3 + d)·vertices + i)·3 + k]: vertex i's displacement k per unit force in d (m/N).
  std::vector<float> g;
  // The same layout: vertex i's linearised rotation k per unit force in d (rad/N, ½∇×u); empty
  // without the rotation correction.
  std::vector<float> w;
  double footprint_radius = 0;
  double max_distance = 0;  // m: the display vertex farthest outside the FEM mesh
  int64_t Bytes() const { return static_cast<int64_t>(g.size() + w.size()) * 4; }
};

// The nodal shares (summing to 1) of a force spread over a tool's footprint: the disc of radius a
// (m) around p on the FEM's boundary (`boundary`: geometry::BoundarySurface of the FEM, its
// vertex indices), perpendicular to n and within a of the tangent plane, lumped by area. What
// one contact of the table stands for.
std::vector<std::pair<int, double>> FootprintWeights(const geometry::TriMesh& boundary,
                                                     const Eigen::Vector3d& p,
                                                     const Eigen::Vector3d& n, double a);

// A contact table's precomputation on this thread gives up between batches of solves, refused
// as kUnavailable, once *flag is true: a background builder that must stop (a node shutting
// down while it builds a palpation case ahead, common/sim/case_bank.h) stops within a batch's
// time, not the table's. Null (every thread's default): never.
void SetPrecomputeCancel(const std::atomic<bool>* flag);
bool PrecomputeCancelled();

// `reachable`: the display vertices a tool can touch (the scene's workspace; not the fixed
// ones). Every one costs 3 back-substitutions.
Expected<ContactResponse> PrecomputeContactResponse(const FemStaticResponse& fem,
                                                    const geometry::TriMesh& display,
                                                    const std::vector<int>& reachable,
                                                    const ContactResponseParams& params);

class ReducedContactModel {
 public:
  // `max_force`: the capacity (N); a larger press is clamped to it and flagged. The table is
  // read-only and may be shared by many models (sessions of one scene).
  static Expected<ReducedContactModel> Create(std::shared_ptr<const ContactResponse> response,
                                              const std::vector<Eigen::Vector3d>& display_rest,
                                              double max_force);
  // One tool at display vertex `contact` pushing with `force` (N). No allocation.
  ReducedStats Press(int contact, const Eigen::Vector3d& force);
  // The same force spread over up to three vertices with weights summing to 1 (a point inside
  // a triangle, by its barycentric coordinates): Σ_k w_k·G_k·F, so the surface does not jump
  // as the tool slides from one vertex to the next.
  ReducedStats Press(const std::array<int, 3>& contacts, const std::array<double, 3>& weights,
                     const Eigen::Vector3d& force);
  // A tool tip held against the surface by a spring of stiffness k (N/m) along the surface
  // normal n (the haptic proxy's coupling), solved together with the tissue: the force on the
  // tissue f = f·n satisfies f = k·nᵀ(tip − (p0 + G·f)) with p0 the contact point at rest and G
  // the compliance there, so f = k·d / (1 + k·nᵀGn), d = nᵀ(tip − p0). Solving the coupling
  // implicitly is what keeps it stable: applying the spring's force to a quasi-static tissue
  // and letting the spring see the moved surface next step diverges whenever k·nᵀGn > 1 (a
  // 300 N/m proxy on a soft 5 cm ball is 1.7). No force when the tip is outside (d ≥ 0).
  ReducedStats PressWithSpring(const std::array<int, 3>& contacts,
                               const std::array<double, 3>& weights, const Eigen::Vector3d& tip,
                               const Eigen::Vector3d& rest_point, const Eigen::Vector3d& normal,
                               double k, Eigen::Vector3d* force_out = nullptr);
  // The compliance (m/N) at a point inside a triangle: nᵀ(Σ_jk w_j·w_k·G_jk)n's matrix, the
  // displacement of the point per unit force spread over the triangle's vertices alike.
  Eigen::Matrix3d ComplianceAt(const std::array<int, 3>& contacts,
                               const std::array<double, 3>& weights) const;
  // The stiffness a spring of k (N/m) along n feels at that point with the tissue behind it
  // (in series), N/m: k / (1 + k·nᵀGn). What the station's local model should render.
  double SeriesStiffness(const std::array<int, 3>& contacts, const std::array<double, 3>& weights,
                         const Eigen::Vector3d& normal, double k) const;
  void Release();  // back to rest
  // The force that moves the contact vertex by `displacement` (m): G_cc⁻¹·δ (clamped to the
  // capacity), then the surface for it. The proxy's position-driven contact.
  ReducedStats Displace(int contact, const Eigen::Vector3d& displacement,
                        Eigen::Vector3d* force_out = nullptr);
  // The tissue's stiffness at a contact, N/m (G_cc⁻¹; symmetric positive definite).
  Eigen::Matrix3d StiffnessAt(int contact) const;
  const std::vector<Eigen::Vector3d>& positions() const { return positions_; }
  const ContactResponse& response() const { return *response_; }
  int VertexCount() const { return static_cast<int>(positions_.size()); }

 private:
  ReducedContactModel() = default;
  int Slot(int contact, ReducedStats& stats) const;
  std::shared_ptr<const ContactResponse> response_;
  std::vector<Eigen::Vector3d> rest_, positions_;
  std::vector<float> u_, w_;  // scratch (3 per vertex): the press's displacement and rotation
  std::vector<Eigen::Matrix3d> compliance_;  // G_cc per slot
  double max_force_ = 0;
};

// ---- 4. Surface twist --------------------------------------------------------------------------

struct SurfaceTwistParams {
  double jaw_radius = 0.009;        // m: the disc the forceps hold
  int64_t max_bytes = 256ll << 20;  // refuse a table larger than this
};

struct SurfaceTwistTable {
  int vertices = 0;                        // display vertices
  std::vector<int> grasps;                 // the precomputed grasp vertices (display indices)
  std::vector<int> slot_of_vertex;         // display vertex → its grasp slot, or the nearest slot
  std::vector<uint8_t> precomputed;        // display vertex → 1 when it has its own slot
  std::vector<float> angle, warp, radial;  // [slot·vertices + i]: TwistField's, per N·m
  std::vector<Eigen::Vector3d> axis;       // per slot: the outward normal at the grasp
  std::vector<double> grasp_compliance;    // per slot: rad per N·m at the jaws
  double jaw_radius = 0;
  double max_distance = 0;  // m: the display vertex farthest outside the FEM mesh
  int64_t Bytes() const {
    return static_cast<int64_t>(angle.size() + warp.size() + radial.size()) * 4;
  }
};

// One FEM solve per reachable display vertex (its unit torque on the jaws' disc).
Expected<SurfaceTwistTable> PrecomputeSurfaceTwist(const FemStaticResponse& fem,
                                                   const geometry::TriMesh& display,
                                                   const std::vector<int>& reachable,
                                                   const SurfaceTwistParams& params);
// Sizes, slots, finiteness and unit axes (a table read from disk is checked before use).
Status ValidateSurfaceTwist(const SurfaceTwistTable& table, size_t display_vertices);
// The twist field of a grasp at display vertex `vertex` (its own slot's, or the nearest one's:
// *fallback says which), for ReducedTwistModel::Create. Allocates: set-up at grasp time.
TwistField SurfaceTwistField(const SurfaceTwistTable& table, int vertex,
                             const std::vector<Eigen::Vector3d>& display_rest,
                             bool* fallback = nullptr);
// dT/dΦ at the jaws (N·m/rad) and the torque capacity for `max_twist` (rad, the largest angle
// any vertex may turn) of a grasp at `vertex`. Read-only, no allocation: any thread.
double SurfaceTwistStiffness(const SurfaceTwistTable& table, int vertex);
double SurfaceTwistCapacity(const SurfaceTwistTable& table, int vertex, double max_twist);
// Each vertex's share of the FEM's boundary area (m², a third of each boundary triangle's; 0 for
// interior vertices).
std::vector<double> BoundaryAreas(const geometry::TetMesh& mesh);
// The FEM boundary vertices the jaws hold around `point` (within jaw_radius, at least the four
// nearest; `area` from BoundaryAreas) and their areas: the loaded face of a surface grasp.
std::vector<int> JawFace(const geometry::TetMesh& mesh, const std::vector<double>& area,
                         const Eigen::Vector3d& point, double jaw_radius,
                         std::vector<double>* face_area = nullptr);

}  // namespace vsurg::tissue
