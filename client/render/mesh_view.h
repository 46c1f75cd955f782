// Draws a session's tissue as the trainee and the instructor see it, in an OpenGL 3.3 core
// context (GLSL 330: client/render/shaders.cpp):
//
//   - the visual surface (common/sim/visual_model.h): a fine skin or organ carried by the coarse
//     physics surface the server moves (SurfaceMapping, computed here from the moved vertices the
//     channel already receives), shaded as skin (wrapped, warm subsurface diffuse) or wet organ
//     (a second sharp lobe), with tone, pores and vessels from a 3D noise texture sampled at each
//     point's rest position, so the pattern moves with the tissue and a twist is seen;
//   - the instrument the task needs (probe, grasper whose jaws close with the button, grip),
//     steel shaded as metal, posed from the stylus;
//   - an operating table with a drape, the key light's shadow map over all of them, a cheap
//     ambient occlusion term;
//   - guidance in the scene (the twist target as an arc on the limb, the current twist, the
//     force on the hand as an arrow) and the HUD (client/render/hud.h).
//
// Quality levels trade those for speed (Quality); the station lowers the level when its frames
// run long (QualityGovernor). Per frame the CPU maps the moved vertices and recomputes normals
// only when something moved.
//
// Units: positions in metres in the scene frame; force in newtons (the arrow 2 cm per newton).
// Threads: the render thread that owns the current OpenGL context (one context per MeshView: the
// GPU objects are made at the first Draw).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "client/render/hud.h"
#include "common/geometry/mesh.h"
#include "common/sim/visual_model.h"

namespace vsurg::client {

namespace gl {
struct Part;
}  // namespace gl
struct InstrumentParts;  // shapes.h
class CutWalls;          // cut_walls.h

// What a search found, drawn over the tissue once it is over (the end-of-trial summary of a
// palpation): a ring on the surface above each lump, as wide as the lump (green when found, red
// when missed), and a pin at each mark (green on the lump it found, joined to the ring's centre;
// orange when it found none). m.
struct Findings {
  struct Ring {
    Eigen::Vector3d surface = Eigen::Vector3d::Zero();  // the surface point above the lump
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();   // the lump's centre (its depth)
    double radius = 0;
    bool found = false;
  };
  struct Pin {
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    int ring = -1;  // the ring it found, -1: none
  };
  std::vector<Ring> rings;
  std::vector<Pin> pins;
};

struct Overlay {
  bool show_stylus = false;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();  // m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N, drawn from the tip
  bool grasping = false, contact = false;
  // Two hands: the second device's instrument (VisualModel::second_instrument), posed from its
  // stylus, its jaws closed while it grasps.
  bool show_second = false;
  Eigen::Vector3d second_tip = Eigen::Vector3d::Zero();  // m
  Eigen::Quaterniond second_orientation = Eigen::Quaterniond::Identity();
  bool second_grasping = false;
  std::vector<std::string> hud;  // the panel's lines, top left: a title line, then the figures
  Guidance guidance;             // the trial's gauges and the target drawn in the scene
  TrialSummary summary;          // the end-of-trial panel
  Findings findings;             // a search's lumps and marks, in the summary only
  bool albedo_only = false;      // tests: the surface pattern without lighting or overlays
};

// kLow: no shadows (a software renderer on a slow machine); kMedium: the shadow map (1024², one
// bilinear comparison); kHigh: a 2048² shadow map with four bilinear comparisons (a 4×4 kernel's
// softness), the per-pixel detail texture (pores, the bump) and the ambient occlusion term. Every
// level draws the skin or organ shading with its tone and vessels (per vertex) and the instrument;
// below high the tissue's diffuse light (key, fill, sky) and broad specular lobe are computed per
// vertex too, its shadow and a wet organ's sharp film lobe per pixel.
enum class Quality { kLow, kMedium, kHigh };
const char* QualityName(Quality q);

// Chooses the level from measured frame times: down a level when the second-slowest of the last
// 30 frames (about the 97th percentile) is over the budget, up again only after 120 frames at
// under 45% of it, never back up to a level that was already too slow, and never above
// `ceiling` (the level the station chose before the trial, StartingQuality).
class QualityGovernor {
 public:
  explicit QualityGovernor(Quality start = Quality::kHigh, double budget_ms = 16.7,
                           Quality ceiling = Quality::kHigh)
      : level_(start), budget_ms_(budget_ms), ceiling_(static_cast<int>(ceiling)) {}
  Quality Update(double frame_ms);
  Quality level() const { return level_; }

 private:
  Quality level_;
  double budget_ms_;
  std::vector<double> window_;
  int fast_frames_ = 0;
  int ceiling_;
};

// The level to start a trial at, from frames drawn before it (the tissue at rest): the highest
// level whose probe frames' 90th percentile is within `share` of the budget, else low. A level
// not probed (empty) counts as too slow. The trial's frames cost more than a frame at rest (the
// moved surface's mapping, normals and upload; the server and the haptic loop beside the
// renderer), hence the share: a level chosen at 60% held its p99 within the budget on every scene
// (docs/BENCHMARKS.md, "Station").
Quality StartingQuality(const std::array<std::vector<double>, 3>& probe_ms, double budget_ms,
                        double share = 0.6);

class MeshView {
 public:
  // `physics` is the physics surface at rest (what the moved indices refer to); `visual` what
  // to draw over it (sim::BuildVisualModel). The camera is fitted to the rest mesh: its longest
  // extent across the view, seen from the side and above the table.
  MeshView(const geometry::TriMesh& physics, sim::VisualModel visual);
  ~MeshView();  // with its context current, as for Draw
  MeshView(const MeshView&) = delete;
  MeshView& operator=(const MeshView&) = delete;

  // Vertices that moved (as a SceneFrame or a monitor's telemetry carries them); indices out of
  // range and non-finite positions are ignored. Returns how many were applied.
  int Apply(const std::vector<int32_t>& indices, const std::vector<Eigen::Vector3f>& positions);
  int Apply(const std::vector<int32_t>& indices, const std::vector<geometry::Vec3>& positions);
  // A cut's faces (a SceneFrame's topology: each face of the physics surface as it is now, a
  // removed one {0, 0, 0}); only where the physics surface is drawn as it is
  // (VisualModel::physics_drawn). A face is taken once each of its vertices has had a position
  // (a copy a cut made is sent as a moved vertex), so none is ever drawn to a vertex not yet
  // placed; a face out of range is ignored. Returns how many were taken.
  int ApplyFaces(const std::vector<int32_t>& indices,
                 const std::vector<std::array<int32_t, 3>>& faces);
  void ResetToRest();
  const std::vector<geometry::Vec3>& positions() const { return positions_; }
  // The visual surface as last drawn (mapped from positions()); visual().surface is that surface
  // at rest (the coarse one below high, VisualModel::coarse_surface).
  const std::vector<Eigen::Vector3f>& visual_positions() const { return fine_; }
  const sim::VisualModel& visual() const { return visual_; }

  void SetQuality(Quality q) { quality_ = q; }
  // Below high, draw the visual model's coarser surface where it has one (on by default; off
  // draws the fine one at every level: tests and benchmarks compare the two).
  void SetCoarseBelowHigh(bool on) { coarse_allowed_ = on; }
  Quality quality() const { return quality_; }
  // Tests: the last of the table's shadow polygons drawn (the instrument's when it is shown, else
  // the tissue's) covers the whole table instead of bounding what casts it. Where the two overlap
  // the tissue's, drawn first, is the one shaded, so an image that changes shows a bound that cut
  // a shadow off.
  void SetCatchersCoverTable(bool on) { catchers_cover_table_ = on; }
  // Looks from `eye` at `centre` (tests, screenshots); the fitted camera otherwise.
  void SetCamera(const Eigen::Vector3d& eye, const Eigen::Vector3d& centre,
                 const Eigen::Vector3d& up);
  Eigen::Vector3d eye() const { return eye_; }
  // Unit vector toward the key light (which casts the shadows).
  Eigen::Vector3d light_direction() const { return key_dir_; }

  // Where a scene point lands in a width × height image (pixels, y down).
  Eigen::Vector2d Project(const geometry::Vec3& p, int width, int height) const;

  // Clears and draws the whole frame into the current context's framebuffer.
  void Draw(int width, int height, const Overlay& overlay);

 private:
  struct Gpu;    // mesh_view_gpu.h
  struct Frame;  // one frame's facts for its passes (mesh_view_draw.cpp)
  // Before a frame (mesh_view.cpp).
  void Prepare(const Overlay& overlay);
  void MakeTissueVertices();
  void MakeResources();
  void UploadMoved(bool remake_tissue);
  // The passes (mesh_view_draw.cpp), in the order Draw runs them.
  Frame BeginFrame(int width, int height, const Overlay& overlay);
  void CasterBoxes(Frame& f);
  void ShadowPass(const Frame& f);
  void DrawCasters(const Frame& f, bool tissue_moved, const std::array<int, 4>& tissue_rect);
  void ScenePass(const Frame& f);
  void InstrumentPass(const Frame& f);
  void TissuePass(const Frame& f);
  void TableShadowPass(const Frame& f);
  void GuidancePass(const Frame& f);
  void FindingsMarks(const Findings& findings);
  // A cut's marked pattern on the tissue as it is (VisualModel::marked_line): each point rides
  // the physics face it lies in at rest (barycentric, found once), so it moves with the patch and
  // goes with a face a cut removed.
  void PatternMarks();
  struct MarkPoint {
    int face = -1;
    Eigen::Vector3d bary = Eigen::Vector3d::Zero();
  };
  std::vector<MarkPoint> mark_points_;  // made at the first PatternMarks
  void DrawPart(const Frame& f, const gl::Part& part, const Eigen::Affine3d& pose, int material,
                const Eigen::Vector3d& albedo, double roughness, double scale, double bump,
                int part_taps);
  // An instrument's jaw (side 0 or 1) about its hinge, opened by `open` rad, posed at `tool`.
  static Eigen::Affine3d JawPose(const Eigen::Affine3d& tool, float open,
                                 const InstrumentParts& shape, int side);
  void DrawTool(const Frame& f, int k);  // the k-th hand's instrument (InstrumentPass)
  void UpdateVisual();
  void MarkPlaced(const std::vector<int32_t>& indices);
  void MarkRestPlaced();
  Eigen::Matrix4d Projection(int width, int height) const;
  Eigen::Matrix4d View() const;
  Eigen::Matrix4d LightViewProjection() const;

  geometry::TriMesh rest_;
  std::vector<geometry::Vec3> positions_;
  sim::VisualModel visual_;
  std::vector<geometry::Triangle> rest_faces_;  // physics_drawn: the surface's faces at rest
  std::vector<uint8_t> placed_;                 // physics_drawn: a vertex has had a position
  std::unique_ptr<CutWalls> walls_;             // a sheet with a thickness: its cut walls
  bool faces_dirty_ = false;                    // the drawn faces changed since the upload
  bool dirty_ = true;
  bool moved_since_shadow_ = true;  // the tissue moved since the shadow map was drawn
  std::vector<Eigen::Vector3f> fine_, fine_normals_;
  geometry::TriMesh moved_;  // the physics surface as last applied, with its normals
  std::unique_ptr<Gpu> gpu_;
  std::unique_ptr<Hud> hud_;
  Quality quality_ = Quality::kHigh;
  bool coarse_allowed_ = true, coarse_active_ = false, catchers_cover_table_ = false;
  // The camera (eye, centre, its up), the world's up (the table's normal) and the key light.
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero(), eye_ = Eigen::Vector3d::UnitY(),
                  up_ = Eigen::Vector3d::UnitZ(), world_up_ = Eigen::Vector3d::UnitZ(),
                  key_dir_ = Eigen::Vector3d::UnitZ();
  // The tissue's footprint on the table (centre, half-axes), darkened by the occlusion term.
  Eigen::Vector3d foot_centre_ = Eigen::Vector3d::Zero(), foot_a_ = Eigen::Vector3d::Zero(),
                  foot_b_ = Eigen::Vector3d::Zero();
  double radius_ = 0.1;
};

}  // namespace vsurg::client
