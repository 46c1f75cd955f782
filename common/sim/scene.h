// Scene files (DESIGN.md "Scenes: model only what a scene needs").
//
// A scene is a JSON file in the scenes/ folder: its mesh, the tissue, the model of its
// deformable region, the haptic coupling and device, the task, and the error budget the chosen
// model meets. Example (scenes/arm-torsion.json):
//
//   { "name": "arm-torsion",
//     "mesh":   { "type": "limb", "preset": "forearm" },
//     "tissue": { "shear_modulus": 12000, "poisson_ratio": 0.47, "density": 1050 },
//     "regions": [ { "name": "forearm",
//                    "model": { "type": "coil", "mode": "limb", "core_radius": 0.02, ... } } ],
//     "haptics": { "device": "touch", "stiffness": 300, "damping": 1.0, "force_scale": 0.05 },
//     "task":   { "type": "twist", "target_deg": 45, "tolerance_deg": 5, "hold_s": 2,
//                 "force_limit_n": 3.0, "time_limit_s": 60 },
//     "error_budget": { "rms": 0.30, "reference": "saint-venant" } }
//
// Mesh types: limb (preset forearm or calf, or length/radius_proximal/radius_distal/segments/
// rings), sphere (radius, particles), obj (path, relative to the scene file), block (size, cells).
// Model types: coil (mode limb or surface), mass-spring (integrator, dt, stiffness, damping,
// volume, support), ring-layer (ring_spacing, rings, chain_stiffness, chain_damping,
// tether_stiffness, dt). Exactly one deformable region per scene: what lies outside its reach is at
// rest and costs nothing. Every error names the field, as a path: "regions[0].model.coils: must be
// ≥ 1".
//
// Set-up code: allocates, reads files.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "common/core/expected.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/tet_generators.h"
#include "common/haptics/blade.h"
#include "common/haptics/needle.h"
#include "common/haptics/proxy.h"
#include "common/haptics/safety.h"
#include "common/haptics/viscoelastic.h"
#include "common/scoring/cut.h"
#include "common/scoring/palpation.h"
#include "common/scoring/trial_metrics.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/cut_membrane.h"
#include "common/tissue/hyperelastic.h"
#include "common/tissue/inclusions.h"
#include "common/tissue/mass_spring.h"
#include "common/tissue/ring_layer.h"

namespace vsurg::sim {

// kMembrane: a cuttable patch in its frame (scene_cut.cpp, tissue/cut_membrane.h).
enum class MeshKind { kLimb, kSphere, kFile, kBlock, kMembrane };
enum class ModelKind { kCoil, kMassSpring, kRingLayer, kReduced, kCutMembrane };
// As scene files spell it: "coil", "mass-spring", "ring-layer", "reduced", "cut-membrane".
const char* ModelKindName(ModelKind kind);
// What is fixed: nothing, the bottom fifth, limb ends, everything on the far side of a plane
// ("support": {"plane": {"point": [x, y, z], "normal": [x, y, z]}}, metres in the scene's frame,
// the normal pointing into the free part), or a named group of a mesh file's vertices
// ("support": {"group": "base"}: an OBJ group or object, an STL solid, a glTF mesh).
enum class Support { kNone, kBottom, kEnds, kPlane, kGroup };

struct MeshSpec {
  MeshKind kind = MeshKind::kLimb;
  geometry::LimbParams limb;
  double radius = 0.05;          // m, sphere
  int particles = 256;           // sphere
  std::string path;              // file (also spelled "obj"), absolute after loading
  double metres_per_unit = 1.0;  // file: its "units" (m, cm, mm, um), as a scale
  // block: a pad on a table ("size": [x, y, z] m, "cells": [nx, ny, nz]); its surface is its FEM
  // grid's boundary (geometry::MakeTetBox), so a reduced model's FEM is the same grid.
  geometry::TetBoxParams block;
  // membrane: the patch (a scene's "cut"."tissue"); its surface is the patch's lattice with room
  // for the particles cuts add (MembraneSurface).
  tissue::CutMembraneParams membrane;
};

// A reduced model precomputed from the scene's own FEM (common/tissue/reduced.h). "contact": the
// Green's-function table of a sphere, every vertex above the support reachable. "twist": the
// twist field of a limb (fixed at its proximal end, the torque on its distal face) for the
// grasp-and-twist.
// contact: a tool presses (Green's functions); twist: a limb twisted at its distal end (the
// twist field); surface-twist: forceps grasp anywhere on an organ and twist about the normal.
enum class ReducedMode { kContact, kTwist, kSurfaceTwist };
struct ReducedSpec {
  ReducedMode mode = ReducedMode::kContact;
  int fem_cells = 8;                // contact on a sphere: the FEM ball's cells per axis (even)
  double fem_size = 0;              // m, contact on a mesh file: the tetrahedra's size (CGAL);
                                    // 0: a twelfth of the mesh's bounding-box diagonal
  int fem_rings = 4;                // twist: rings in the FEM cylinder's cross-section (1..8)
  double footprint_radius = 0.005;  // m, contact: the tool's contact disc
  double max_force = 10;            // N, contact: the capacity; a larger press is clamped
  // Contact: the table's rotation correction (tissue/reduced.h, 3.): right for the corotational
  // law, worse against a hyperelastic press past a few mm and five times the cost per press.
  bool rotation = true;
  double max_twist = 1.5707963267948966;  // rad, twist: the largest turn any vertex may take
  int levels = 6;             // twist with a hyperelastic law: the table's load levels on each side
  double jaw_radius = 0.009;  // m, surface twist: the disc the forceps hold
};

struct RegionSpec {
  std::string name;
  ModelKind kind = ModelKind::kCoil;
  tissue::CoilSpringParams coil;
  tissue::TwistMode coil_mode = tissue::TwistMode::kLimb;
  tissue::MassSpringBuildParams mass_spring;
  tissue::Integrator integrator = tissue::Integrator::kImplicitEuler;
  double dt = 1e-3;  // s, mass-spring and ring-layer step
  Support support = Support::kBottom;
  geometry::Vec3 support_point = geometry::Vec3::Zero();    // m, kPlane
  geometry::Vec3 support_normal = geometry::Vec3::UnitZ();  // unit, kPlane
  std::string support_group;                                // kGroup
  tissue::RingLayerParams ring;
  ReducedSpec reduced;
};

struct HapticsSpec {
  std::string device = "touch";
  haptics::DeviceLimits limits = haptics::TouchLimits();
  haptics::ProxyParams proxy;
  double force_scale = 1.0;       // rendered force = tissue force × scale (desktop devices cannot
                                  // render limb torques at true scale)
  double hold_stiffness = 200.0;  // N/m, the grasp holds the tip on the grasped point
  double min_lever = 0.005;       // m, the twist force's lever when the tip is on the axis
                                  // (forceps jaws in surface mode)
  // m: a free tool this close to the surface gets the surface ahead of contact in its local
  // model (model-mediated teleoperation), so a station behind a delay begins contact itself.
  // 3 cm covers a 0.1 m/s approach over a 300 ms round trip. 0: never.
  double lookahead = 0.03;
  // The contact in the station's local model where the tissue model has none of its own:
  //   kViscoelastic (the default): the proxy's spring in series with the tissue point's fitted
  //     stiffness and damping (haptics/viscoelastic.h), integrated by the station over its own
  //     motion; before the first fit, the proxy's spring;
  //   kFitted: one slope fitted to the force over the depth (haptics::StiffnessFit): predicts a
  //     press, but lets go late (the tissue is viscous);
  //   kProxy: the proxy's spring (the first local model).
  // Scene files: "contact_model": "viscoelastic" | "fitted" | "proxy".
  enum class ContactModel { kViscoelastic, kFitted, kProxy };
  ContactModel contact_model = ContactModel::kViscoelastic;
  // The tissue point under the proxy as the server's fit finds it when the scene is pressed
  // (`vsurg-sim contact-law`): k_t (N/m) and b (N·s/m), sent with a station's surface so that a
  // contact's first round trip is rendered as the tissue, not as the proxy's spring on a rigid
  // surface. 0: not known (the proxy's spring). Scene files: "tissue_stiffness",
  // "tissue_damping".
  double tissue_stiffness = 0, tissue_damping = 0;
  // The tissue's static curve under the proxy (`vsurg-sim contact-law`): the station's surface
  // renders a contact's first round trip along it, where k_t·S is the tangent at one depth
  // (haptics::TissueCurve). Scene files: "tissue_curve": [[yield_m, force_n], ...].
  haptics::TissueCurve tissue_curve;
  // The tissue's surface sent with a station's join (haptics/tissue_surface.h). Model only what a
  // scene needs: a press scene's task is the contact, so by default it has it; a twist scene's
  // is the grasp, whose model comes with the answers, and a limb's surface (12 k triangles, a
  // quarter of a megabyte with each session's creation) would cost every station and the site
  // for a contact the task does not score. Scene files: "station_surface": true | false.
  std::optional<bool> station_surface;
  bool StationSurface(scoring::TaskKind task) const {
    return station_surface.value_or(task == scoring::TaskKind::kPress);
  }
};

// How the station draws the tissue (never what the server simulates): its material, and its
// visual surface: a named file (a scan finer than the physics mesh, in the scene's frame), or
// else one generated at about `min_triangles` (a limb's skin, an organ refined). Scene files
// say "visual": {"material": "skin" | "organ" | "kidney", "mesh": "file", "units": "mm",
// "min_triangles": N}, every field optional; without them a limb is skin and anything else an
// organ.
enum class VisualMaterial { kSkin, kOrgan, kKidney };
const char* VisualMaterialName(VisualMaterial m);
struct VisualSpec {
  VisualMaterial material = VisualMaterial::kSkin;
  int min_triangles = 20000;   // the visual surface is refined until it has at least this many
  std::string mesh;            // a file of the visual surface (absolute after loading), or empty
  double metres_per_unit = 1;  // its "units"
};

struct Scene {
  std::string name, description;
  std::string source;  // the file it was read from
  MeshSpec mesh;
  double shear_modulus = 12e3, poisson_ratio = 0.47, density = 1050;
  // "tissue.volume": "vertices": a reduced model's tables integrate the volume constraint at the
  // vertices (tissue::FemParams::nodal_volume); "element" (false), the default.
  bool volume_at_vertices = false;
  // "tissue.law" (scene_law.cpp): the tissue's constitutive law. "linear" (the default): small
  // strains, the corotational FEM and every table built from it. "neo-hookean" or "exponential"
  // (with "stiffening" b > 0): the hyperelastic FEM's law (tissue/hyperelastic.h), which a reduced
  // twist region carries in load levels (tissue/twist_table.h); no other model has it yet.
  enum class Law { kLinear, kNeoHookean, kExponential };
  Law law = Law::kLinear;
  double stiffening = 0;  // b, dimensionless: the exponential law's
  // "tissue.relaxation": [{"g": share, "tau_s": s}, ...] (scene_law.cpp): the torque of a reduced
  // twist region relaxes by G(t) = g∞ + Σ g_i·e^{−t/τ_i} while the twist is held
  // (tissue::TorqueRelaxation); empty: elastic.
  std::vector<tissue::PronyTerm> relaxation;
  std::vector<tissue::Inclusion> inclusions;  // lumps of another stiffness (inclusions.h)
  // A palpation's cases: each attempt draws its own lumps (DrawInclusions) into `inclusions`
  // (DrawCase); unset: the scene's own inclusions are the case.
  std::optional<tissue::InclusionDraw> cases;
  double case_margin = 0.02;  // m, the drawn lumps' least distance from the palpable rim
  RegionSpec region;
  HapticsSpec haptics;
  // A needle's tissue (haptics/needle.h; scene files: "needle", scene_needle.cpp): its layers
  // under the block's top and its target. Set: the tool is a needle, whatever touches the skin.
  std::optional<haptics::NeedleTissueSpec> needle;
  // A cut scene's blade and marked pattern (scene_cut.cpp; the patch is mesh.membrane). Set: the
  // tool is a blade and the task a cut.
  struct CutSpec {
    haptics::BladeParams blade;  // its stiffnesses the patch's own (set when a session builds)
    scoring::CutPattern pattern;
    // The second hand's grasper ("grasper"; unset: the blade alone): its jaws take the particle
    // under them when they close within `reach` m of the patch, and hold it toward themselves by
    // a spring of `stiffness` N/m (the station's second device; simulation.h OnSecondHandStylus).
    struct Grasper {
      double stiffness = 2000;  // N/m
      double reach = 0.004;     // m
    };
    std::optional<Grasper> grasper;
  };
  std::optional<CutSpec> cut;
  scoring::TaskSpec task;
  VisualSpec visual;
  double error_budget_rms = 0.1;  // relative RMS displacement error the model meets
  std::string error_reference;    // what that error is measured against
  // What one full-rate station on this scene costs its node, in cores ("cost": {"core_per_station":
  // x}, measured by bench/scene_cost.sh on a 2-core node; 0: not stated). A node's default
  // capacity is what 70% of its cores hold at the dearest of its scenes (docs/SCALING.md).
  double core_per_station = 0;
};

// One user can never deny the others service: a scene may not ask for more memory per session
// than this. Checked when a scene is read (from the mesh parameters) and again when a session is
// built (from the real vertex count, for meshes read from files).
inline constexpr size_t kSessionMemoryBudgetBytes = size_t{512} << 20;
// The memory one session of a scene with `surface_vertices` needs, estimated from per-vertex
// costs measured on the shipped scenes (scene.cpp), bytes.
// `reduced_contact`: a reduced model's contact table, quadratic in the vertices (its twist field
// is linear, like the coil's).
size_t EstimatedSessionBytes(ModelKind model, size_t surface_vertices, bool reduced_contact = true);
// kResourceExhausted, naming `field`, when the estimate is over the budget.
Status CheckSessionMemory(ModelKind model, size_t surface_vertices, const std::string& field,
                          bool reduced_contact = true);

Expected<Scene> ParseScene(const std::string& json_text, const std::string& source);
// The scene file's "needle" object into `s.needle` (scene_needle.cpp); nothing when absent.
Status ParseNeedle(const nlohmann::json& root, Scene& s);
// The scene file's "tissue.law" and "tissue.stiffening" into `s.law` (scene_law.cpp), after the
// region (only a reduced twist region carries a law other than linear).
Status ParseLaw(const nlohmann::json& root, Scene& s);
// The scene file's "cut" object into `s.cut` and `s.mesh.membrane` (scene_cut.cpp); nothing when
// absent. A membrane mesh, the cut-membrane model and a cut task go together.
Status ParseCut(const nlohmann::json& root, Scene& s);
// A membrane's surface: the patch's lattice at rest, then as many spare vertices (at the origin,
// in no triangle) as cuts may add, so a cut scene's vertex count never changes and each particle
// of the patch is the vertex of its index.
Expected<geometry::TriMesh> MembraneSurface(const tissue::CutMembraneParams& params);
Expected<Scene> LoadScene(const std::string& path);

// A scene's mesh made concrete: the surface, and the centreline for limbs (empty otherwise).
struct SceneMesh {
  geometry::TriMesh surface;
  std::vector<geometry::Vec3> centreline;
  std::map<std::string, std::vector<int>> groups;  // a mesh file's named groups (vertices)
};
Expected<SceneMesh> BuildSceneMesh(const MeshSpec& spec);

// The vertices a support holds fixed: nothing; the bottom fifth of the height (resting on a
// table); or the ends, 1% of the length at each end of a limb lying along z.
std::vector<int> SupportedVertices(const geometry::TriMesh& mesh, Support support);
// A region's support, any kind: kInvalidArgument naming regions[0].model.support when its group
// is not among `groups`.
Expected<std::vector<int>> SupportedVertices(const geometry::TriMesh& mesh,
                                             const RegionSpec& region,
                                             const std::map<std::string, std::vector<int>>& groups);
// The same support on a FEM mesh of the surface: a group holds the FEM's boundary vertices whose
// nearest surface vertex the group holds (`surface_held`); the other kinds apply as to the
// surface.
std::vector<int> SupportedFemVertices(const geometry::TetMesh& fem,
                                      const geometry::TriMesh& surface,
                                      const std::vector<int>& surface_held,
                                      const RegionSpec& region);

// The scenes folder: $VSURG_SCENES, else scenes/ beside the executable's ../../ (the build tree)
// or ../share/vsurg/scenes (an install), else the source tree's scenes/ compiled in.
std::string ScenesDirectory();
// "arm-torsion" → <scenes>/arm-torsion.json; a path ending in .json is loaded as is.
Expected<Scene> LoadSceneByName(const std::string& name_or_path);

}  // namespace vsurg::sim
