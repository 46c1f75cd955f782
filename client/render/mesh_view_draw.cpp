// MeshView::Draw (mesh_view.h) as its passes, in the order they draw: the shadow map from the
// key light, the background (the table, kept between frames), the instrument, the tissue, the
// shadows on the table, the guidance marks, the HUD. The GPU's objects are made and updated
// before them (MeshView::Prepare, mesh_view.cpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "client/render/mesh_view.h"
#include "client/render/mesh_view_gpu.h"
#include "client/render/shaders.h"
#include "common/geometry/bvh.h"

namespace vsurg::client {

using namespace gl;  // the view's own GL plumbing (gl_resources.h)

namespace {

using Rect = std::array<int, 4>;  // texels x0, y0, x1, y1

// The colour of the tissue a cut exposes (linear RGB): dermis, red from its blood supply.
const Eigen::Vector3d kCutInterior(0.42, 0.07, 0.06);

bool NoRect(const Rect& r) {
  return r[2] <= r[0] || r[3] <= r[1];
}

Rect Unite(Rect a, const Rect& b) {
  if (NoRect(b)) return a;
  for (int k : {0, 1}) a[k] = std::min(a[k], b[k]);
  for (int k : {2, 3}) a[k] = std::max(a[k], b[k]);
  return a;
}

// The texels of a size² shadow map a box's corners cover, seen from the light, widened by two.
Rect ShadowTexels(const Eigen::Matrix4d& light, const std::vector<Eigen::Vector3d>& box, int size) {
  Rect r{size, size, 0, 0};
  for (const Eigen::Vector3d& p : box) {
    const Eigen::Vector4d clip = light * p.homogeneous();
    if (!clip.allFinite()) return Rect{0, 0, size, size};
    for (int axis = 0; axis < 2; ++axis) {
      const double t = std::clamp((clip[axis] / clip.w() + 1) * 0.5 * size, -1.0, size + 1.0);
      r[axis] = std::min(r[axis], static_cast<int>(std::floor(t)) - 2);
      r[axis + 2] = std::max(r[axis + 2], static_cast<int>(std::ceil(t)) + 2);
    }
  }
  for (int& edge : r) edge = std::clamp(edge, 0, size);
  return r;
}

void CopyRect(GLuint from, GLuint to, const Rect& r) {
  if (NoRect(r)) return;
  glCopyImageSubData(from, GL_TEXTURE_2D, 0, r[0], r[1], 0, to, GL_TEXTURE_2D, 0, r[0], r[1], 0,
                     r[2] - r[0], r[3] - r[1], 1);
}

}  // namespace

// One frame's facts every pass reads.
struct MeshView::Frame {
  explicit Frame(const Overlay& o) : overlay(o) {}
  const Overlay& overlay;
  int width = 0, height = 0;
  GLint target = 0;  // the caller's framebuffer
  bool stylus = false;
  Eigen::Affine3d tool = Eigen::Affine3d::Identity();  // the instrument's pose
  float open = 0;                                      // its jaws' opening, rad
  // Two hands: the second hand's instrument, when shown (Overlay::show_second).
  bool second = false;
  Eigen::Affine3d tool2 = Eigen::Affine3d::Identity();
  float open2 = 0;
  bool Shown(int k) const { return k == 0 ? stylus : second; }
  const Eigen::Affine3d& Pose(int k) const { return k == 0 ? tool : tool2; }
  float Open(int k) const { return k == 0 ? open : open2; }
  Quality q = Quality::kHigh;
  bool shadows = false;
  Eigen::Matrix4d light = Eigen::Matrix4d::Identity(), view_projection = light;
  // What casts shadows, as boxes' corners: the tissue's (its drawn and its physics surface) and
  // the instrument's (in its own frame ±5 cm across, from 1 cm below the tip to 21 cm above,
  // around every instrument's parts and open jaws). The shadow pass draws and the table's
  // shadows are shaded only where these can fall; without shadows neither is made.
  std::vector<Eigen::Vector3d> tissue_box, tool_box;
  int taps = 0;  // shadow-map taps per pixel
  bool detail = false, ao = false;
  Eigen::Vector3d fill = Eigen::Vector3d::Zero();  // the fill light's direction
  Eigen::Vector3d drape{0.035, 0.15, 0.17};        // the table's colour
};

void MeshView::Draw(int width, int height, const Overlay& overlay) {
  Prepare(overlay);
  const Frame f = BeginFrame(width, height, overlay);
  if (f.shadows) ShadowPass(f);
  ScenePass(f);
  // The instrument first: it is nearer than the tissue where they overlap, so the tissue's
  // pixels behind it fail the depth test before they are shaded.
  if ((f.stylus || f.second) && !overlay.albedo_only) InstrumentPass(f);
  TissuePass(f);
  if (!overlay.albedo_only) {
    if (f.shadows) TableShadowPass(f);
    GuidancePass(f);
  }
  glBindVertexArray(0);
  glUseProgram(0);
  // The HUD.
  if (!overlay.albedo_only &&
      (!overlay.hud.empty() || overlay.guidance.show || overlay.summary.show)) {
    if (!hud_) hud_ = std::make_unique<Hud>();
    hud_->Draw(width, height, overlay.hud, overlay.guidance, overlay.summary);
  }
}

MeshView::Frame MeshView::BeginFrame(int width, int height, const Overlay& overlay) {
  Gpu& g = *gpu_;
  Frame f(overlay);
  f.width = width, f.height = height;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &f.target);
  f.stylus = overlay.show_stylus && overlay.tip.allFinite() &&
             overlay.orientation.coeffs().allFinite() && !overlay.albedo_only;
  if (f.stylus) f.tool = Eigen::Translation3d(overlay.tip) * overlay.orientation.normalized();
  f.open = overlay.grasping ? 0.0f : g.tools[0].shape.open_rad;
  f.second = g.tools[1].made && overlay.show_second && overlay.second_tip.allFinite() &&
             overlay.second_orientation.coeffs().allFinite() && !overlay.albedo_only;
  if (f.second)
    f.tool2 = Eigen::Translation3d(overlay.second_tip) * overlay.second_orientation.normalized();
  f.open2 = overlay.second_grasping ? 0.0f : g.tools[1].shape.open_rad;
  f.q = quality_;
  f.shadows = f.q != Quality::kLow && !overlay.albedo_only;
  f.light = LightViewProjection();
  f.view_projection = Projection(width, height) * View();
  f.taps = f.shadows ? (f.q == Quality::kHigh ? 4 : 1) : 0;
  f.detail = f.q == Quality::kHigh || overlay.albedo_only;
  f.ao = f.q == Quality::kHigh;
  f.fill = ((eye_ - centre_).normalized() - 0.3 * world_up_).normalized();
  if (f.shadows) CasterBoxes(f);
  return f;
}

Eigen::Affine3d MeshView::JawPose(const Eigen::Affine3d& tool, float open,
                                  const InstrumentParts& shape, int side) {
  const Eigen::Vector3f hinge = shape.hinge;
  Eigen::Affine3f local = Eigen::Translation3f(hinge) *
                          Eigen::AngleAxisf(side ? -open : open, Eigen::Vector3f::UnitX()) *
                          Eigen::Translation3f(-hinge);
  if (side) local = local * Eigen::AngleAxisf(std::numbers::pi_v<float>, Eigen::Vector3f::UnitZ());
  return Eigen::Affine3d(tool.matrix() * local.matrix().cast<double>());
}

void MeshView::CasterBoxes(Frame& f) {
  Gpu& g = *gpu_;
  if (g.tissue_bounds_stale) {
    // Where the tissue can cast: its box (both surfaces) for the shadow map's texels, and the
    // polygon on the table its casters' shadow falls within; again only when it moved.
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = -lo;
    for (const auto& p : fine_)
      lo = lo.cwiseMin(p.cast<double>()), hi = hi.cwiseMax(p.cast<double>());
    for (const auto& p : moved_.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    g.tissue_lo = lo;
    g.tissue_hi = hi;
    const TableFrame t = Table(centre_, world_up_, visual_.table_height, radius_);
    ShadowBound bound(key_dir_, world_up_, visual_.table_height, t.e1, t.e2);
    if (coarse_active_ || !g.caster_vao)
      for (const auto& p : fine_) bound.Add(p.cast<double>());
    else
      for (const auto& p : moved_.positions) bound.Add(p);
    g.tissue_shadow = bound.Corners(radius_ * 0.03);
    g.tissue_bounds_stale = false;
  }
  const Eigen::Vector3d &lo = g.tissue_lo, &hi = g.tissue_hi;
  for (int c = 0; c < 8; ++c) {
    f.tissue_box.emplace_back(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(),
                              c & 4 ? hi.z() : lo.z());
    for (int k = 0; k < 2; ++k)
      if (f.Shown(k))
        f.tool_box.push_back(f.Pose(k) * Eigen::Vector3d(c & 1 ? 0.05 : -0.05, c & 2 ? 0.05 : -0.05,
                                                         c & 4 ? 0.21 : -0.01));
  }
}

void MeshView::ShadowPass(const Frame& f) {
  Gpu& g = *gpu_;
  // 1. The shadow map: depth from the key light of the tissue and the instrument; drawn again
  // only when one of them or the light moved (a trainee holding still costs no shadow pass).
  std::array<double, 51> shadow_key{};
  for (int k = 0; k < 2; ++k) {
    const Eigen::Matrix4d pose = f.Shown(k) ? f.Pose(k).matrix() : Eigen::Matrix4d::Zero();
    std::copy(pose.data(), pose.data() + 16, shadow_key.begin() + 17 * k);
    shadow_key[17 * k + 16] = f.Open(k);
  }
  shadow_key[34] = static_cast<double>(f.q);
  std::copy(f.light.data(), f.light.data() + 16, shadow_key.begin() + 35);
  if (!(moved_since_shadow_ || shadow_key != g.shadow_key)) return;
  // The tissue's casters are drawn again when it or the light moved (SetCamera moves the light
  // with the centre), else its kept depth is copied back (below).
  const bool tissue_moved =
      moved_since_shadow_ ||
      !std::equal(shadow_key.begin() + 35, shadow_key.end(), g.shadow_key.begin() + 35);
  moved_since_shadow_ = false;
  g.shadow_key = shadow_key;
  const int size = f.q == Quality::kHigh ? 2048 : 1024;
  g.EnsureShadowMap(size);
  glBindFramebuffer(GL_FRAMEBUFFER, g.shadow_fbo);
  glViewport(0, 0, size, size);
  // Only the texels the casters can cover are cleared and drawn, with those the last pass wrote
  // (the rest still hold the first clear): the tissue's box and the tool's, projected along the
  // light, widened by two texels. A software renderer clears and rasterises per 64² tile, and
  // the casters cover a third of the map or less. The clear is a copy from a map kept at the
  // far plane (Gpu::far_depth): on llvmpipe a depth clear, scissored or whole, took 0.4-0.5 ms
  // of a moving frame at medium and the copy 0.01 ms.
  const std::array<int, 4> tissue_rect = ShadowTexels(f.light, f.tissue_box, size),
                           tool_rect = ShadowTexels(f.light, f.tool_box, size);
  const std::array<int, 4> rect = Unite(tissue_rect, tool_rect);
  const std::array<int, 4> clear = Unite(rect, g.shadow_written);
  g.shadow_written = rect;
  CopyRect(g.far_depth, g.shadow_map, clear);
  glEnable(GL_SCISSOR_TEST);
  glScissor(clear[0], clear[1], std::max(clear[2] - clear[0], 0), std::max(clear[3] - clear[1], 0));
  glEnable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(1.5f, 2.0f);
  glUseProgram(g.shadow);
  SetMatrix(g.shadow, "uLightViewProj", f.light);
  SetMatrix(g.shadow, "uModel", Eigen::Matrix4d::Identity());
  DrawCasters(f, tissue_moved, tissue_rect);
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDisable(GL_SCISSOR_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(f.target));
}

// The shadow map's casters: the tissue (or its depth kept from the last pass that drew it) and
// the instrument.
void MeshView::DrawCasters(const Frame& f, bool tissue_moved,
                           const std::array<int, 4>& tissue_rect) {
  Gpu& g = *gpu_;
  // The tissue: its depth as the last pass that drew it left it when neither it nor the light
  // moved since (a copy of a third of the map or less, against rasterising its casters), else
  // drawn and kept for the passes after.
  if (!tissue_moved && !NoRect(tissue_rect) && g.tissue_written == tissue_rect) {
    CopyRect(g.tissue_depth, g.shadow_map, tissue_rect);
  } else {
    glEnable(GL_CULL_FACE);  // one side casts: half the triangles
    if (coarse_active_) {
      // Below high, the coarse visual surface is what is drawn, and its far side is the cheaper
      // caster: a quarter of the fine surface's triangles and under half the physics surface's
      // (the arm: 5.9 k against 12.4 k), closed and wound outward (tested).
      glCullFace(GL_FRONT);
      g.tissue.Draw();
    } else if (g.caster_vao) {
      glCullFace(g.caster_cull);
      glBindVertexArray(g.caster_vao);
      glDrawElements(GL_TRIANGLES, g.caster_count, GL_UNSIGNED_INT, nullptr);
    } else {
      glCullFace(GL_BACK);
      if (visual_.physics_drawn) glDisable(GL_CULL_FACE);  // an open sheet casts from both sides
      g.tissue.Draw();
    }
    glDisable(GL_CULL_FACE);
    g.tissue_written = {};
    if (!NoRect(tissue_rect)) {
      CopyRect(g.shadow_map, g.tissue_depth, tissue_rect);
      g.tissue_written = tissue_rect;
    }
  }
  for (int k = 0; k < 2; ++k) {
    if (!f.Shown(k)) continue;
    const Gpu::Tool& t = g.tools[static_cast<size_t>(k)];
    SetMatrix(g.shadow, "uModel", f.Pose(k).matrix());
    t.steel.Draw();
    t.handle.Draw();
    if (t.shape.has_jaws)
      for (int side = 0; side < 2; ++side) {
        SetMatrix(g.shadow, "uModel", JawPose(f.Pose(k), f.Open(k), t.shape, side).matrix());
        t.jaw.Draw();
      }
  }
}

void MeshView::DrawPart(const Frame& f, const Part& part, const Eigen::Affine3d& pose, int material,
                        const Eigen::Vector3d& albedo, double roughness, double scale, double bump,
                        int part_taps) {
  Gpu& g = *gpu_;
  const GLuint s = g.Scene(material, part_taps, f.detail && scale > 1, f.ao, f.overlay.albedo_only);
  glUseProgram(s);
  SetMatrix(s, "uViewProj", f.view_projection);
  SetMatrix(s, "uLightViewProj", f.light);
  SetVec3(s, "uEye", eye_);
  SetVec3(s, "uKeyDir", key_dir_);
  SetVec3(s, "uKeyColour", Eigen::Vector3d(1.36, 1.27, 1.14));
  SetVec3(s, "uFillDir", f.fill);
  SetVec3(s, "uFillColour", Eigen::Vector3d(0.20, 0.22, 0.28));
  SetVec3(s, "uUp", world_up_);
  SetVec3(s, "uSky", Eigen::Vector3d(0.24, 0.26, 0.31));
  SetVec3(s, "uGround", Eigen::Vector3d(0.05, 0.07, 0.08));
  SetFloat(s, "uShadowTexel", 1.0 / std::max(g.shadow_size, 1));
  SetFloat(s, "uTableHeight", visual_.table_height);
  SetInt(s, "uShadowMap", 0);
  SetInt(s, "uDetail", 1);
  SetVec3(s, "uFootCentre", foot_centre_);
  SetVec3(s, "uFootA", foot_a_);
  SetVec3(s, "uFootB", foot_b_);
  SetMatrix(s, "uModel", pose.matrix());
  SetMatrix3(s, "uNormalMatrix", pose.linear().inverse().transpose());
  SetVec3(s, "uAlbedo", albedo);
  SetFloat(s, "uRoughness", roughness);
  SetFloat(s, "uDetailScale", scale);
  SetFloat(s, "uBumpDepth", bump);
  part.Draw();
}

// The scene's state, and the background: drawn again only when what it shows changed, else
// copied.
void MeshView::ScenePass(const Frame& f) {
  Gpu& g = *gpu_;
  glViewport(0, 0, f.width, f.height);
  glEnable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, f.shadows ? g.shadow_map : 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_3D, g.detail);
  glActiveTexture(GL_TEXTURE0);
  if (f.overlay.albedo_only) {
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  } else {
    // The background: drawn again only when what it shows changed, else copied.
    const std::array<double, 9> key = {double(f.width), double(f.height), double(f.q),
                                       eye_.x(),        eye_.y(),         eye_.z(),
                                       centre_.x(),     centre_.y(),      centre_.z()};
    if (!g.background_fbo) {
      glGenFramebuffers(1, &g.background_fbo);
      glGenRenderbuffers(1, &g.background_colour);
      glGenRenderbuffers(1, &g.background_depth);
    }
    if (key != g.background_key) {
      glBindRenderbuffer(GL_RENDERBUFFER, g.background_colour);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, f.width, f.height);
      glBindRenderbuffer(GL_RENDERBUFFER, g.background_depth);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, f.width, f.height);
      glBindFramebuffer(GL_FRAMEBUFFER, g.background_fbo);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                g.background_colour);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                                g.background_depth);
      glClearColor(0.10f, 0.11f, 0.13f, 1.0f);
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      DrawPart(f, g.table, Eigen::Affine3d::Identity(), shaders::kDrape, f.drape, 0.85, 220, 0.0004,
               0);
      glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(f.target));
      g.background_key = key;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, g.background_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, static_cast<GLuint>(f.target));
    glBlitFramebuffer(0, 0, f.width, f.height, 0, 0, f.width, f.height, GL_COLOR_BUFFER_BIT,
                      GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(f.target));
    glClear(GL_DEPTH_BUFFER_BIT);
  }
}

void MeshView::InstrumentPass(const Frame& f) {
  for (int k = 0; k < 2; ++k)
    if (f.Shown(k)) DrawTool(f, k);
}

void MeshView::DrawTool(const Frame& f, int k) {
  const Gpu::Tool& t = gpu_->tools[static_cast<size_t>(k)];
  const Eigen::Affine3d& pose = f.Pose(k);
  const Eigen::Vector3d steel(0.78, 0.78, 0.80);
  DrawPart(f, t.steel, pose, shaders::kMetal, steel, 0.28, 1, 0, f.taps);
  DrawPart(f, t.handle, pose, shaders::kPlastic, Eigen::Vector3d(0.035, 0.04, 0.05), 0.45, 1, 0,
           f.taps);
  if (t.shape.has_jaws)
    for (int side = 0; side < 2; ++side)
      DrawPart(f, t.jaw, JawPose(pose, f.Open(k), t.shape, side), shaders::kMetal,
               Eigen::Vector3d(0.70, 0.71, 0.73), 0.38, 1, 0, f.taps);
}

void MeshView::TissuePass(const Frame& f) {
  Gpu& g = *gpu_;
  const MaterialLook look = LookOf(visual_.material);
  // The visual surface is closed and wound outward (tested): its back half is culled, which on a
  // software renderer halves the triangles set up. An open sheet drawn as its physics surface (a
  // cut's patch) shows both sides: a flap the cut freed may fold over (the shader lights the side
  // it sees).
  if (!visual_.physics_drawn) {
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
  }
  DrawPart(f, g.tissue, Eigen::Affine3d::Identity(), look.shader, look.albedo, look.roughness,
           look.detail_scale, look.bump_depth, f.taps);
  glDisable(GL_CULL_FACE);
  // A cut's walls: the dermis it exposed, a deep red from its blood supply, wetter than the skin.
  if (g.walls.count > 0)
    DrawPart(f, g.walls, Eigen::Affine3d::Identity(), look.shader, kCutInterior, 0.35,
             look.detail_scale, 0, f.taps);
}

// The shadows on the table: blended over the background's table, only where the tissue's and the
// tool's shadows can fall (the table covers most of the frame; shading all of it for a shadow a
// fifth its size is what cost the most).
void MeshView::TableShadowPass(const Frame& f) {
  Gpu& g = *gpu_;
  // The tissue's and the tool's shadows each within its own polygon on the table
  // (ShadowBound: the casters' own points flattened onto it along the key light, widened by
  // more than the shadow's soft edge). (A screen box around both, or around each, shaded
  // several times the shadow's own pixels: the table covers most of the frame.) The tissue's
  // polygon lies 0.1 mm above the tool's and both write depth, so where they overlap the
  // table's shadow is blended once.
  const TableFrame t = Table(centre_, world_up_, visual_.table_height, radius_);
  const Eigen::Vector3d table_origin = visual_.table_height * world_up_;
  const Eigen::Vector2d centre(t.centre.dot(t.e1), t.centre.dot(t.e2));
  ShapeMesh catcher;
  const auto add_catcher = [&](const std::vector<Eigen::Vector2d>& corners, double below) {
    if (corners.size() < 3) return;
    const auto base = static_cast<uint32_t>(catcher.positions.size());
    for (const Eigen::Vector2d& c : corners) {
      // Within the table: each corner clamped to its square.
      const Eigen::Vector2d v = centre + (c - centre).cwiseMax(-t.half).cwiseMin(t.half);
      catcher.positions.push_back(
          (table_origin + v.x() * t.e1 + v.y() * t.e2 - below * world_up_).cast<float>());
      catcher.normals.push_back(world_up_.cast<float>());
    }
    for (uint32_t i = 1; i + 1 < corners.size(); ++i)
      catcher.indices.insert(catcher.indices.end(), {base, base + i, base + i + 1});
  };
  std::vector<Eigen::Vector2d> table;  // SetCatchersCoverTable: the whole table's corners
  if (catchers_cover_table_)
    for (int c = 0; c < 4; ++c)
      table.emplace_back(centre.x() + ((c == 1 || c == 2) ? t.half : -t.half),
                         centre.y() + (c >= 2 ? t.half : -t.half));
  // The table's own level.
  add_catcher(catchers_cover_table_ && !f.stylus ? table : g.tissue_shadow, 0.0005);
  for (int k = 0; k < 2; ++k) {
    if (!f.Shown(k)) continue;
    const Gpu::Tool& tool = g.tools[static_cast<size_t>(k)];
    ShadowBound bound(key_dir_, world_up_, visual_.table_height, t.e1, t.e2);
    const auto add = [&](const ShapeMesh& part, const Eigen::Affine3d& pose) {
      for (const Eigen::Vector3f& p : part.positions) bound.Add(pose * p.cast<double>());
    };
    add(tool.shape.steel, f.Pose(k));
    add(tool.shape.handle, f.Pose(k));
    if (tool.shape.has_jaws)
      for (int side = 0; side < 2; ++side)
        add(tool.shape.jaw, JawPose(f.Pose(k), f.Open(k), tool.shape, side));
    add_catcher(catchers_cover_table_ ? table : bound.Corners(radius_ * 0.03), 0.0006 + 1e-4 * k);
  }
  if (!catcher.indices.empty()) {
    g.catcher.Upload(Interleave(catcher), catcher.indices, GL_STREAM_DRAW);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    DrawPart(f, g.catcher, Eigen::Affine3d::Identity(), shaders::kShadowCatcher, f.drape, 1, 1, 0,
             f.taps);
    glDisable(GL_BLEND);
  }
}

void MeshView::GuidancePass(const Frame& f) {
  Gpu& g = *gpu_;
  // 3. Guidance marks, unlit: the twist target's band and the twist so far as arcs, the force
  // on the hand as an arrow.
  g.marks.Clear();
  const Guidance& gd = f.overlay.guidance;
  if (gd.show && gd.twist && visual_.twist_radius > 0) {
    const bool at_tool = visual_.instrument == sim::Instrument::kGrasper;
    if (!at_tool || f.stylus) {
      const Eigen::Vector3d centre =
          at_tool ? Eigen::Vector3d(f.overlay.tip + 0.004 * world_up_) : visual_.twist_centre;
      const Eigen::Vector3d axis = visual_.twist_axis;
      const Eigen::Vector3d zero = at_tool ? axis.unitOrthogonal() : world_up_;
      const double sign = gd.current < 0 ? -1 : 1, r = visual_.twist_radius;
      const double thick = std::max(0.0025, r * 0.07);
      g.marks.Arc(centre, axis, zero, r, 0, sign * 2 * std::numbers::pi * 0.999, thick * 0.35,
                  Eigen::Vector4f(0.85f, 0.88f, 0.92f, 0.35f));
      g.marks.Arc(centre, axis, zero, r, sign * (gd.target - gd.tolerance),
                  sign * (gd.target + gd.tolerance), thick * 1.6,
                  Eigen::Vector4f(0.25f, 0.85f, 0.45f, 0.75f));
      const bool within = std::abs(std::abs(gd.current) - gd.target) <= gd.tolerance;
      g.marks.Arc(centre, axis, zero, r * 1.06, 0, gd.current, thick,
                  within ? Eigen::Vector4f(0.3f, 0.95f, 0.5f, 1.0f)
                         : Eigen::Vector4f(1.0f, 0.70f, 0.15f, 1.0f));
    }
  }
  FindingsMarks(f.overlay.findings);
  PatternMarks();
  if (f.stylus && f.overlay.force.allFinite() && f.overlay.force.norm() > 0.05) {
    const Eigen::Vector3d head = f.overlay.tip + 0.02 * f.overlay.force;
    const Eigen::Vector3d neck = f.overlay.tip + 0.75 * (head - f.overlay.tip);
    const Eigen::Vector4f yellow(1.0f, 0.86f, 0.15f, 0.9f);
    g.marks.Tube(f.overlay.tip, neck, 0.0008, yellow);
    g.marks.Cone(neck, head, 0.0022, yellow);
  }
  if (g.marks.vertices() > 0) {
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDepthMask(GL_FALSE);
    glUseProgram(g.flat);
    SetMatrix(g.flat, "uViewProj", f.view_projection);
    glBindVertexArray(g.flat_vao);
    glBindBuffer(GL_ARRAY_BUFFER, g.flat_vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.marks.data.size() * sizeof(float)),
                 g.marks.data.data(), GL_STREAM_DRAW);
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(g.marks.vertices()));
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
  }
}

void MeshView::PatternMarks() {
  const std::vector<Eigen::Vector3d>& line = visual_.marked_line;
  if (line.size() < 2 || !visual_.physics_drawn) return;
  const std::vector<geometry::Triangle>& faces = visual_.surface.triangles;
  if (mark_points_.empty()) {  // once: the rest face under each point (within 0.1 mm of it)
    const geometry::Bvh rest(rest_);
    for (const Eigen::Vector3d& p : line) {
      const geometry::ClosestHit hit = rest.Closest(rest_.positions, p, 1e-4);
      mark_points_.push_back({hit.triangle, hit.barycentric});
    }
  }
  const auto at = [&](const MarkPoint& m, Eigen::Vector3d& out) {
    if (m.face < 0) return false;
    const geometry::Triangle& t = faces[static_cast<size_t>(m.face)];
    if (t == geometry::Triangle{0, 0, 0}) return false;  // cut away with its piece
    out = m.bary[0] * positions_[t[0]] + m.bary[1] * positions_[t[1]] +
          m.bary[2] * positions_[t[2]] + 0.0003 * world_up_;
    return out.allFinite();
  };
  const Eigen::Vector4f marker(0.30f, 0.16f, 0.62f, 0.9f);  // a surgical skin marker's violet
  // Two neighbours the cut parted (one on its piece, one beside it) are not joined across the gap.
  Eigen::Vector3d a, b;
  for (size_t i = 0; i + 1 < mark_points_.size(); ++i)
    if (at(mark_points_[i], a) && at(mark_points_[i + 1], b) &&
        (b - a).norm() < 2 * (line[i + 1] - line[i]).norm() + 0.0005)
      gpu_->marks.Tube(a, b, 0.00035, marker);
}

// A search's findings (Findings): rings lifted a millimetre off the surface along the normal
// there (from the lump's centre to the point above it; the table's up for a lump at the surface),
// pins standing 6 mm off it. Bad values are skipped, never drawn.
void MeshView::FindingsMarks(const Findings& findings) {
  Gpu& g = *gpu_;
  const Eigen::Vector4f green(0.25f, 0.9f, 0.45f, 0.95f), red(0.95f, 0.22f, 0.2f, 0.95f),
      orange(1.0f, 0.62f, 0.1f, 0.95f);
  const auto normal_at = [&](const Findings::Ring& r) {
    const Eigen::Vector3d n = r.surface - r.centre;
    return n.norm() > 1e-4 ? Eigen::Vector3d(n.normalized()) : world_up_;
  };
  for (const Findings::Ring& r : findings.rings) {
    if (!r.surface.allFinite() || !r.centre.allFinite() || !(r.radius > 0 && r.radius < radius_))
      continue;
    const Eigen::Vector3d n = normal_at(r);
    g.marks.Arc(r.surface + 0.001 * n, n, n.unitOrthogonal(), r.radius, 0,
                2 * std::numbers::pi * 0.999, std::max(0.0012, r.radius * 0.18),
                r.found ? green : red);
  }
  for (const Findings::Pin& p : findings.pins) {
    if (!p.at.allFinite()) continue;
    const bool hit = p.ring >= 0 && p.ring < static_cast<int>(findings.rings.size());
    const Eigen::Vector3d n = hit ? normal_at(findings.rings[p.ring]) : world_up_;
    const Eigen::Vector4f colour = hit ? green : orange;
    g.marks.Tube(p.at, p.at + 0.006 * n, 0.0006, colour);
    g.marks.Cone(p.at + 0.006 * n, p.at + 0.0095 * n, 0.0018, colour);
    if (hit && findings.rings[p.ring].surface.allFinite())
      g.marks.Tube(p.at + 0.001 * n, findings.rings[p.ring].surface + 0.001 * n, 0.0005, colour);
  }
}

}  // namespace vsurg::client
