// A cuttable membrane: a thin patch of tissue (skin, or the gauze of a pattern-cutting drill) held
// taut in a frame, as triangles of springs, whose topology a blade changes while it deforms
// (DESIGN.md "Cutting").
//
// Model. The patch is a rectangle in the plane z = 0 (normal +z) meshed as a triangular lattice
// (equilateral triangles of side size_x / cells, the rows closed at the sides by half
// triangles), its rim held by the frame. Each triangle
// T carries its own three edge springs, k = E t A_T / |e|² (the triangulated-membrane stiffness in
// the form of Van Gelder, "Approximate simulation of elastic membranes by triangulated spring
// meshes", J. Graphics Tools 1998), so an interior edge gets one spring from each side; rest
// lengths are the mesh's shortened by the frame's pre-strain, which gives the patch its
// out-of-plane stiffness. Masses lumped, ρ t A_T / 3 per corner. The solver is MassSpringModel's
// implicit Euler.
//
// Cutting by node snapping (Nienhuys & van der Stappen, "A surgery simulation supporting cuts and
// finite element deformation", MICCAI 2001): the cut runs along mesh edges; the node ahead of the
// cut's front is first moved, in the rest state, onto the blade's path when that moves it by at
// most snap_fraction of the edge and leaves every triangle around it with angles of at least
// min_angle (else the cut follows the edge as it is). Cutting an edge separates the triangles on
// its two sides at both its ends: each node is given one particle per wedge of its triangles that
// uncut edges still join (MassSpringModel::SplitParticle, the springs of a wedge's triangles moved
// to its particle, the masses shared again). Why this method: it makes no new triangles, so no
// sliver and no T-junction can arise (element splitting makes both), the springs of a triangle
// never change but for their ends and, after a snap, their rest lengths, and the cost per cut
// edge is a constant (two fans of at most eight triangles); its price is that a cut can only pass
// through nodes, which snapping makes good to a fraction of an edge. The virtual node algorithm
// (Molino, Bao & Fedkiw 2004) cuts inside elements without snapping, at the cost of duplicated
// elements and embedded surfaces, which a patch meshed at the blade's resolution does not need.
//
// A cut that closes a loop frees the piece inside: its triangles are removed from the patch (the
// piece is taken out, as in the drill), its particles held still, and the piece counted.
//
// Units: m, kg, s, N, Pa. Threads: one (the deformation thread); Cut and Step never allocate
// within the room reserved at Create (max_particles).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::tissue {

using Vec2 = Eigen::Vector2d;

struct CutMembraneParams {
  double size_x = 0.08, size_y = 0.08;  // m, the frame's inner rectangle, centred on the origin
  int cells = 32;                       // triangles' edges across size_x
  double thickness = 1.2e-3;            // m
  double youngs_modulus = 1.18e6;       // Pa, in-plane
  double density = 1100;                // kg/m³
  double damping = 0.02;                // N·s/m, every spring
  double pretension = 0.02;             // the frame's pre-strain (rest lengths shortened by it)
  double snap_fraction = 0.5;  // a node moves onto the cut by at most this share of an edge
  double min_angle_deg = 20;   // no snap that leaves a triangle angle below this
  // A cut advances to the node ahead when the blade has passed this share of the edge to it.
  double advance_fraction = 0.6;
  // A spring stretched past this strain (over its unloaded length) has failed: an edge whose
  // springs have all failed tears as a cut would (Tear). Skin: 0.54, the mean failure strain of
  // excised human back skin (Ní Annaidh et al., J. Mech. Behav. Biomed. Mater. 5, 2012).
  double failure_strain = 0.54;
  int max_particles = 0;  // room for the copies cuts make; 0: twice the nodes
};

// Checks each field by name ("thickness: must be > 0 m").
Status CheckCutMembrane(const CutMembraneParams& p);

class CutMembrane {
 public:
  static Expected<CutMembrane> Create(const CutMembraneParams& params);

  // Carves the cut from `from` toward `to` (points in the patch's rest plane, m): starts at the
  // cut node nearest `from` within an edge's length (a cut continued, or a branch off it), else
  // at the node nearest `from` (a new cut, that node snapped onto `from`), and walks node to
  // node while `to` is past advance_fraction of the next edge. Returns the edges cut. A segment
  // outside the patch or not finite cuts nothing.
  int Cut(const Vec2& from, const Vec2& to);
  // One implicit step of dt s; false when the model diverged (it is then back at rest).
  bool Step(double dt);
  // A force (N) at `at` (rest plane), on the side of the cut the point is on: half on the particle
  // nearest it, half shared by that particle's neighbours in its wedge (a blade's edge bears on
  // about an edge's length of tissue, not on one node; a point load would strain the lattice
  // around it past the tissue's failure strain where the real tissue is not). Zero clears it.
  // Held until changed.
  void Load(const Vec2& at, const Vec3& force);

  // A grasper's jaws on the patch: the particle under `at` (rest plane) held toward `target` (m)
  // by a spring-damper of `stiffness` N/m (inside the implicit solve). Replaces the last hold; the
  // same `at` keeps the same particle (jaws that stay closed while the hand moves). Release lets
  // go. The force on the jaws (N) is HoldForce.
  void Hold(const Vec2& at, const Vec3& target, double stiffness);
  void Release();
  Vec3 HoldForce() const;
  // Tears every edge whose springs are all past failure_strain (after a step); returns how many
  // tore. Torn edges are cut edges too, counted apart (torn_edges). Edges with a node within
  // `spare` m of `blade` (rest plane) are left to the blade: at its front the tissue is cut, its
  // fracture the blade's model (haptics/blade.h), and a point load's strain there is the
  // lattice's, not the tissue's.
  int Tear(const Vec2& blade = Vec2::Constant(1e9), double spare = 0);
  int torn_edges() const { return torn_; }

  // The patch drawn: its triangles (particles), the removed ones left out.
  struct Face {
    std::array<int32_t, 3> v;
  };
  int FaceCount() const { return static_cast<int>(tris_.size()); }
  bool Removed(int face) const { return tris_[face].removed; }
  Face face(int f) const { return {tris_[f].v}; }
  const std::vector<Vec3>& positions() const { return model_->positions(); }
  const MassSpringModel& model() const { return *model_; }
  const CutMembraneParams& params() const { return p_; }
  int node_count() const { return static_cast<int>(node_rest_.size()); }
  // The particles the patch has room for (max_particles, or twice the nodes).
  int ParticleRoom() const;
  // The rest-plane position of particle i (after snapping).
  Vec2 Rest(int particle) const;
  // The original node a particle is a copy of.
  int NodeOf(int particle) const { return node_of_[particle]; }
  // Whether the frame holds the particle (its node is on the rim).
  bool OnFrame(int particle) const { return node_fixed_[node_of_[particle]]; }

  // The cut so far: its edges (pairs of nodes), in the order they were cut.
  const std::vector<std::array<int32_t, 2>>& cut_edges() const { return cut_; }
  bool EdgeCut(int a, int b) const;
  int freed_pieces() const { return freed_; }
  int snaps() const { return snaps_; }
  // What a blade pressing on the patch first meets (N/m): a point force's stiffness in the plane
  // (plane stress) and out of it (the frame's tension), both with the load spread over half an
  // edge and the rim at half the patch's smaller side.
  double InPlaneStiffness() const;
  double NormalStiffness() const;
  double EdgeLength() const { return h_; }  // m, the lattice's edge

 private:
  struct Tri {
    std::array<int32_t, 3> v;       // particles
    std::array<int32_t, 3> n;       // their nodes
    std::array<int32_t, 3> spring;  // spring k joins v[k] and v[(k + 1) % 3]
    std::array<int32_t, 3> across;  // the triangle across edge k (-1: the rim)
    bool removed = false;
  };
  static constexpr int kMaxFan = 8;  // triangles around a node (six inside), and neighbours

  CutMembrane() = default;
  void BuildGrid();
  Status BuildModel();
  int NearestNode(const Vec2& p, bool on_cut_only, double within) const;
  int NextNode(int a, const Vec2& to, const Vec2& on, const Vec2& dir) const;
  void Snap(int node, const Vec2& a, const Vec2& to);
  void SnapTo(int node, const Vec2& at);
  void MoveCorner(int t, int corner, int particle);
  bool SnapKeepsQuality(int node, const Vec2& at) const;
  void CutEdge(int a, int b);
  void SeparateFan(int node);
  void ShareMasses(int node);
  void FreeLoosePieces();
  void FreePiece(int label);
  double RestLength(const Tri& t, int k) const;

  CutMembraneParams p_;
  std::optional<MassSpringModel> model_;  // set by Create
  double h_ = 0;
  std::vector<Vec2> node_rest_;  // per node
  std::vector<bool> node_fixed_, node_on_cut_;
  std::vector<std::array<int32_t, kMaxFan>> fan_;  // triangles around each node (-1: none)
  std::vector<std::array<int32_t, kMaxFan>> adj_;  // neighbours of each node (-1: none)
  std::vector<std::array<uint8_t, kMaxFan>> adj_cut_;
  std::vector<Tri> tris_;
  std::vector<int32_t> node_of_;  // per particle
  std::vector<std::array<int32_t, 2>> cut_;
  std::vector<int32_t> label_, stack_;  // flood fill, per triangle (sized at Create)
  int freed_ = 0, snaps_ = 0;
  void ClearLoad();
  std::array<int32_t, kMaxFan + 1> loaded_{};  // the particles the load is spread over
  int loaded_count_ = 0;
  int32_t held_ = -1;
  Vec3 hold_target_ = Vec3::Zero();
  Vec2 hold_at_ = Vec2::Zero();
  double hold_k_ = 0;
  int torn_ = 0;
  int ParticleUnder(const Vec2& at) const;
  int32_t front_ = -1;  // the node the last cut ended at
};

}  // namespace vsurg::tissue
