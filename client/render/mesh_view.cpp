// MeshView (mesh_view.h): the view's state, the camera, the moved vertices applied and mapped
// onto the visual surface, and its GPU objects made and kept up to date before each frame
// (Prepare). The passes that draw a frame are in mesh_view_draw.cpp.
#include "client/render/mesh_view.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>

#include "client/render/cut_walls.h"
#include "client/render/gl_resources.h"
#include "client/render/mesh_view_gpu.h"
#include "client/render/shaders.h"
#include "client/render/shapes.h"

namespace vsurg::client {

using namespace gl;  // the view's own GL plumbing (gl_resources.h)

const char* QualityName(Quality q) {
  switch (q) {
    case Quality::kLow:
      return "low";
    case Quality::kMedium:
      return "medium";
    case Quality::kHigh:
      return "high";
  }
  return "high";
}

Quality QualityGovernor::Update(double frame_ms) {
  window_.push_back(frame_ms);
  if (window_.size() < 30) return level_;
  std::vector<double> sorted = window_;
  std::nth_element(sorted.begin(), sorted.begin() + 28, sorted.end());
  const double second_slowest = sorted[28];
  std::nth_element(sorted.begin(), sorted.begin() + 27, sorted.end());
  const double p90 = sorted[27];
  window_.clear();
  int level = static_cast<int>(level_);
  if (second_slowest > budget_ms_ && level > 0) {
    ceiling_ = level - 1;  // this level was too slow: never again
    --level;
    fast_frames_ = 0;
  } else if (p90 < 0.45 * budget_ms_ && level < ceiling_) {
    fast_frames_ += 30;
    if (fast_frames_ >= 120) ++level, fast_frames_ = 0;
  } else {
    fast_frames_ = 0;
  }
  level_ = static_cast<Quality>(level);
  return level_;
}

Quality StartingQuality(const std::array<std::vector<double>, 3>& probe_ms, double budget_ms,
                        double share) {
  for (Quality q : {Quality::kHigh, Quality::kMedium}) {
    std::vector<double> t = probe_ms[static_cast<size_t>(q)];
    if (t.empty()) continue;
    const size_t k = std::min(t.size() - 1, (t.size() * 9) / 10);
    std::nth_element(t.begin(), t.begin() + static_cast<ptrdiff_t>(k), t.end());
    if (t[k] <= share * budget_ms) return q;
  }
  return Quality::kLow;
}

MeshView::MeshView(const geometry::TriMesh& physics, sim::VisualModel visual)
    : rest_(physics), positions_(physics.positions), visual_(std::move(visual)), moved_(physics) {
  if (visual_.physics_drawn) {
    rest_faces_ = visual_.surface.triangles;
    placed_.assign(rest_.positions.size(), 0);
    MarkRestPlaced();
    if (visual_.sheet_thickness > 0) walls_ = std::make_unique<CutWalls>(rest_faces_);
  }
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = -lo;
  for (const auto& p : rest_.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  if (rest_.positions.empty()) lo = hi = Eigen::Vector3d::Zero();
  centre_ = 0.5 * (lo + hi);
  radius_ = std::max(0.5 * (hi - lo).norm(), 1e-3);
  // The table's up is the view's up; across the screen the longest extent at right angles to
  // it; the camera looks from the side and above.
  world_up_ = visual_.up.normalized();
  up_ = world_up_;
  const Eigen::Vector3d extent = hi - lo;
  Eigen::Vector3d across = Eigen::Vector3d::UnitX();
  double longest = -1;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d axis = Eigen::Vector3d::Unit(a);
    if (std::abs(axis.dot(up_)) > 0.9) continue;
    if (extent[a] > longest + 1e-9) longest = extent[a], across = axis;
  }
  // A limb is seen from the side its scripted grasp is on (+x); an organ from −y, where a
  // kidney's hilum faces.
  // The footprint the table's occlusion darkens: the rest mesh's extent across the table.
  {
    const Eigen::Vector3d half = 0.5 * (hi - lo), mid = 0.5 * (lo + hi);
    foot_centre_ = mid - (mid.dot(world_up_) - visual_.table_height) * world_up_;
    for (int k = 0, used = 0; k < 3; ++k) {
      if (std::abs(Eigen::Vector3d::Unit(k).dot(world_up_)) > 0.9) continue;
      (used++ == 0 ? foot_a_ : foot_b_) = Eigen::Vector3d::Unit(k) * std::max(half[k], 1e-3);
    }
  }
  const Eigen::Vector3d view = visual_.instrument == sim::Instrument::kGrip
                                   ? Eigen::Vector3d(up_.cross(across).normalized())
                                   : Eigen::Vector3d(across.cross(up_).normalized());
  centre_ += 0.2 * radius_ * up_;  // a little above the tissue: the instrument comes from there
  // A limb is worked at its distal end (+z): the view turns toward it, so the wrist's end and
  // the twist's dial are seen three-quarters on.
  const Eigen::Vector3d toward_work = visual_.instrument == sim::Instrument::kGrip
                                          ? Eigen::Vector3d(0.45 * across)
                                          : Eigen::Vector3d::Zero();
  eye_ = centre_ + radius_ * 2.9 * (view + 0.62 * up_ + toward_work).normalized();
  // The key light from above and to one side: shadows fall beside the tool and the tissue,
  // where the trainee sees them.
  key_dir_ = (world_up_ + 0.30 * view - 0.55 * across).normalized();
}

MeshView::~MeshView() {
  hud_.reset();
  gpu_.reset();
}

void MeshView::SetCamera(const Eigen::Vector3d& eye, const Eigen::Vector3d& centre,
                         const Eigen::Vector3d& up) {
  eye_ = eye;
  centre_ = centre;
  up_ = up.normalized();
}

namespace {

// Moved vertices into `positions`: out-of-range indices and non-finite positions are skipped.
template <typename Point>
int ApplyMoved(std::vector<geometry::Vec3>& positions, const std::vector<int32_t>& indices,
               const std::vector<Point>& moved) {
  int applied = 0;
  const size_t n = std::min(indices.size(), moved.size());
  for (size_t k = 0; k < n; ++k) {
    const int32_t i = indices[k];
    if (i < 0 || static_cast<size_t>(i) >= positions.size() || !moved[k].allFinite()) continue;
    positions[i] = moved[k].template cast<double>();
    ++applied;
  }
  return applied;
}

}  // namespace

int MeshView::Apply(const std::vector<int32_t>& indices,
                    const std::vector<Eigen::Vector3f>& positions) {
  const int applied = ApplyMoved(positions_, indices, positions);
  MarkPlaced(indices);
  dirty_ = dirty_ || applied > 0;
  return applied;
}

int MeshView::Apply(const std::vector<int32_t>& indices,
                    const std::vector<geometry::Vec3>& positions) {
  const int applied = ApplyMoved(positions_, indices, positions);
  MarkPlaced(indices);
  dirty_ = dirty_ || applied > 0;
  return applied;
}

void MeshView::MarkPlaced(const std::vector<int32_t>& indices) {
  for (int32_t i : indices)
    if (i >= 0 && static_cast<size_t>(i) < placed_.size()) placed_[i] = 1;
}

int MeshView::ApplyFaces(const std::vector<int32_t>& indices,
                         const std::vector<std::array<int32_t, 3>>& faces) {
  if (!visual_.physics_drawn) return 0;
  std::vector<geometry::Triangle>& drawn = visual_.surface.triangles;
  const size_t n = std::min(indices.size(), faces.size());
  int taken = 0;
  for (size_t k = 0; k < n; ++k) {
    const int32_t f = indices[k];
    if (f < 0 || static_cast<size_t>(f) >= drawn.size()) continue;
    const geometry::Triangle face{faces[k][0], faces[k][1], faces[k][2]};
    const bool removed = face == geometry::Triangle{0, 0, 0};
    bool placed = true;
    for (int v : face)
      placed = placed && v >= 0 && static_cast<size_t>(v) < placed_.size() && placed_[v];
    if (!removed && !placed) continue;
    // A copy's rest position is its original's (the tissue's tone and detail are read there).
    for (int c = 0; c < 3 && !removed; ++c)
      if (face[c] != rest_faces_[f][c])
        visual_.surface.positions[face[c]] = rest_.positions[rest_faces_[f][c]];
    if (drawn[f] != face) drawn[f] = face, ++taken;
  }
  faces_dirty_ = faces_dirty_ || taken > 0;
  dirty_ = dirty_ || taken > 0;
  return taken;
}

void MeshView::ResetToRest() {
  positions_ = rest_.positions;
  dirty_ = true;
  if (visual_.physics_drawn && visual_.surface.triangles != rest_faces_) {
    visual_.surface.triangles = rest_faces_;
    visual_.surface.positions = rest_.positions;
    faces_dirty_ = true;
  }
  if (visual_.physics_drawn) std::fill(placed_.begin(), placed_.end(), 0), MarkRestPlaced();
}

void MeshView::MarkRestPlaced() {
  for (const geometry::Triangle& t : rest_faces_)
    for (int v : t) placed_[v] = 1;
}

Eigen::Matrix4d MeshView::Projection(int width, int height) const {
  return Frustum(static_cast<double>(width) / std::max(height, 1), radius_ * 0.1, radius_ * 12);
}

Eigen::Matrix4d MeshView::View() const {
  return LookAt(eye_, centre_, up_);
}

Eigen::Matrix4d MeshView::LightViewProjection() const {
  // An orthographic box along the key light around the tissue, the instrument above it and the
  // table's shadowed patch.
  const double r = radius_ * 1.7;
  const Eigen::Vector3d helper = std::abs(key_dir_.dot(Eigen::Vector3d::UnitZ())) > 0.9
                                     ? Eigen::Vector3d::UnitX()
                                     : Eigen::Vector3d::UnitZ();
  return Ortho(r, 0.05 * r, 6 * r) * LookAt(centre_ + key_dir_ * 3 * r, centre_, helper);
}

Eigen::Vector2d MeshView::Project(const geometry::Vec3& p, int width, int height) const {
  const Eigen::Vector4d clip = Projection(width, height) * View() * p.homogeneous();
  const Eigen::Vector2d ndc = clip.head<2>() / clip.w();
  return {(ndc.x() + 1) * 0.5 * width, (1 - ndc.y()) * 0.5 * height};
}

void MeshView::UpdateVisual() {
  // The physics surface's vertex normals, then the visual surface mapped from it and its own
  // normals: only when a vertex moved.
  moved_.positions = positions_;
  if (visual_.physics_drawn) moved_.triangles = visual_.surface.triangles;  // a cut's faces
  geometry::ComputeVertexNormals(moved_);
  if (visual_.physics_drawn) {
    fine_.resize(positions_.size());
    for (size_t i = 0; i < positions_.size(); ++i) fine_[i] = positions_[i].cast<float>();
  } else {
    visual_.mapping.Apply(moved_.positions, moved_.normals, fine_);
  }
  geometry::VertexNormals(visual_.surface.triangles, fine_, fine_normals_, world_up_.cast<float>());
  dirty_ = false;
}

// The GPU's objects before a frame: made at the first, the tissue's buffers made again when the
// drawn surface changes (below high, the coarser one), the moved vertices uploaded.
void MeshView::Prepare(const Overlay& overlay) {
  const bool first = !gpu_;
  if (first) gpu_ = std::make_unique<Gpu>();
  Gpu& g = *gpu_;
  // Below high, the coarser visual surface where there is one (VisualModel::coarse_surface):
  // the two trade places in visual_, and the tissue's buffers are made again for it.
  const bool want_coarse = coarse_allowed_ && quality_ != Quality::kHigh && !overlay.albedo_only &&
                           !visual_.coarse_surface.positions.empty();
  bool remake_tissue = first;
  if (want_coarse != coarse_active_) {
    std::swap(visual_.surface, visual_.coarse_surface);
    std::swap(visual_.mapping, visual_.coarse_mapping);
    coarse_active_ = want_coarse;
    dirty_ = true;
    remake_tissue = true;
  }
  if (first) {
    g.shadow = Link(shaders::kShadowVertex, shaders::kShadowFragment);
    g.flat = Link(shaders::kFlatVertex, shaders::kFlatFragment);
  }
  remake_tissue = remake_tissue || faces_dirty_;  // a cut changed the faces drawn
  faces_dirty_ = false;
  if (remake_tissue) MakeTissueVertices();
  if (first) MakeResources();
  if (dirty_) UploadMoved(remake_tissue);
}

// The tissue: rest positions fixed, positions and normals rewritten when they move.
void MeshView::MakeTissueVertices() {
  Gpu& g = *gpu_;
  const size_t fine_count = visual_.surface.positions.size();
  g.indices.clear();
  g.indices.reserve(visual_.surface.triangles.size() * 3);
  for (const auto& t : visual_.surface.triangles)
    for (int v : t) g.indices.push_back(static_cast<uint32_t>(v));
  // Per vertex: position and normal (rewritten as they move), rest position, and the broad
  // detail (tone, vessels) read once from the detail texture at an eighth of its scale: it
  // varies over centimetres, which the visual surface's vertices resolve, and a texture fetch
  // fewer per pixel is what a software renderer feels most.
  const double broad = LookOf(visual_.material).detail_scale * 0.125;
  g.upload.assign(fine_count * 11, 0.0f);
  for (size_t i = 0; i < fine_count; ++i) {
    const Eigen::Vector3d& rest = visual_.surface.positions[i];
    for (int k = 0; k < 3; ++k) g.upload[11 * i + 6 + k] = static_cast<float>(rest[k]);
    const Eigen::Vector4f d = SampleDetail(rest * broad);
    g.upload[11 * i + 9] = d[0];
    g.upload[11 * i + 10] = d[2];
  }
  dirty_ = true;
}

// What is made once per context: the shadow caster, the table, the instrument, the marks'
// buffer, the detail texture.
void MeshView::MakeResources() {
  Gpu& g = *gpu_;
  // The shadow caster (Gpu::caster_vao), when the physics surface can be one.
  const geometry::TopologyReport topology = geometry::CheckTopology(rest_);
  const double volume = geometry::SignedVolume(rest_);
  // Fewer triangles draw a polygon for a round shadow's outline (the 256-particle sphere's 512
  // did, visibly, on the table); 2,000 put some 64 edges around a round silhouette.
  constexpr size_t kMinCasterTriangles = 2000;
  if (topology.Closed() && topology.ConsistentlyOriented() && volume != 0 &&
      std::isfinite(volume) && rest_.triangles.size() >= kMinCasterTriangles) {
    g.caster_cull = volume > 0 ? GL_FRONT : GL_BACK;
    std::vector<uint32_t> caster_indices;
    caster_indices.reserve(rest_.triangles.size() * 3);
    for (const auto& t : rest_.triangles)
      for (int v : t) caster_indices.push_back(static_cast<uint32_t>(v));
    g.caster_count = static_cast<GLsizei>(caster_indices.size());
    g.caster_upload.assign(rest_.positions.size() * 3, 0.0f);
    glGenVertexArrays(1, &g.caster_vao);
    glGenBuffers(1, &g.caster_vbo);
    glGenBuffers(1, &g.caster_ebo);
    glBindVertexArray(g.caster_vao);
    glBindBuffer(GL_ARRAY_BUFFER, g.caster_vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.caster_upload.size() * sizeof(float)),
                 g.caster_upload.data(), GL_DYNAMIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.caster_ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(caster_indices.size() * 4),
                 caster_indices.data(), GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glBindVertexArray(0);
  }
  // The table: a square of drape under the tissue.
  const TableFrame t = Table(centre_, world_up_, visual_.table_height, radius_);
  ShapeMesh table;
  for (int c = 0; c < 4; ++c) {
    const Eigen::Vector3d p = t.centre + t.half * ((c == 1 || c == 2) ? t.e1 : -t.e1) +
                              t.half * (c >= 2 ? t.e2 : -t.e2) - 0.0005 * world_up_;
    table.positions.push_back(p.cast<float>());
    table.normals.push_back(world_up_.cast<float>());
  }
  table.indices = {0, 1, 2, 0, 2, 3};
  g.table.Upload(Interleave(table), table.indices, GL_STATIC_DRAW);
  const std::array<std::optional<sim::Instrument>, 2> kinds = {visual_.instrument,
                                                               visual_.second_instrument};
  for (size_t k = 0; k < g.tools.size(); ++k) {
    if (!kinds[k]) continue;
    Gpu::Tool& tool = g.tools[k];
    tool.shape = MakeInstrument(*kinds[k]);
    tool.steel.Upload(Interleave(tool.shape.steel), tool.shape.steel.indices, GL_STATIC_DRAW);
    tool.handle.Upload(Interleave(tool.shape.handle), tool.shape.handle.indices, GL_STATIC_DRAW);
    tool.jaw.Upload(Interleave(tool.shape.jaw), tool.shape.jaw.indices, GL_STATIC_DRAW);
    tool.made = true;
  }
  glGenVertexArrays(1, &g.flat_vao);
  glGenBuffers(1, &g.flat_vbo);
  glBindVertexArray(g.flat_vao);
  glBindBuffer(GL_ARRAY_BUFFER, g.flat_vbo);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 7 * sizeof(float), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 7 * sizeof(float),
                        reinterpret_cast<const void*>(3 * sizeof(float)));
  glBindVertexArray(0);
  const std::vector<unsigned char>& texels = DetailTexels();
  glGenTextures(1, &g.detail);
  glBindTexture(GL_TEXTURE_3D, g.detail);
  glTexImage3D(GL_TEXTURE_3D, 0, GL_RGBA8, kDetailSize, kDetailSize, kDetailSize, 0, GL_RGBA,
               GL_UNSIGNED_BYTE, texels.data());
  glGenerateMipmap(GL_TEXTURE_3D);
  // Bilinear within the nearer mip level: half the texels of trilinear filtering, and at the
  // distance a trainee sees the tissue the levels' seams do not show.
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_NEAREST);
  glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  for (GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R})
    glTexParameteri(GL_TEXTURE_3D, wrap, GL_REPEAT);
}

// The moved vertices mapped onto the visual surface and uploaded, with the shadow caster's.
void MeshView::UploadMoved(bool remake_tissue) {
  Gpu& g = *gpu_;
  const size_t fine_count = visual_.surface.positions.size();
  moved_since_shadow_ = true;
  g.tissue_bounds_stale = true;
  UpdateVisual();
  for (size_t i = 0; i < fine_count; ++i) {
    float* v = &g.upload[11 * i];
    for (int k = 0; k < 3; ++k) {
      v[k] = fine_[i][k];
      v[3 + k] = fine_normals_[i][k];
    }
  }
  if (remake_tissue || !g.tissue.vao) {
    g.tissue.Upload(g.upload, g.indices, GL_DYNAMIC_DRAW, 11);
  } else {
    glBindBuffer(GL_ARRAY_BUFFER, g.tissue.vbo);
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(g.upload.size() * sizeof(float)),
                    g.upload.data());
  }
  if (walls_) {  // a cut sheet's walls, where its vertices now are
    walls_->Build(moved_, visual_.sheet_thickness, g.wall_mesh);
    g.walls.Upload(gl::Interleave(g.wall_mesh), g.wall_mesh.indices, GL_DYNAMIC_DRAW);
  }
  if (g.caster_vao) {
    for (size_t i = 0; i < moved_.positions.size(); ++i)
      for (int k = 0; k < 3; ++k)
        g.caster_upload[3 * i + k] = static_cast<float>(moved_.positions[i][k]);
    glBindBuffer(GL_ARRAY_BUFFER, g.caster_vbo);
    glBufferSubData(GL_ARRAY_BUFFER, 0,
                    static_cast<GLsizeiptr>(g.caster_upload.size() * sizeof(float)),
                    g.caster_upload.data());
  }
}

}  // namespace vsurg::client
