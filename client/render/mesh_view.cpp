#include "client/render/mesh_view.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <random>
#include <string>

#include "client/render/shaders.h"
#include "client/render/shapes.h"

namespace vsurg::client {
namespace {

// The view matrix looking from `eye` at `centre` (what gluLookAt builds).
Eigen::Matrix4d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& centre,
                       const Eigen::Vector3d& up) {
  const Eigen::Vector3d f = (centre - eye).normalized();
  const Eigen::Vector3d s = f.cross(up).normalized();
  const Eigen::Vector3d u = s.cross(f);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

// What glFrustum builds: a 35° vertical field of view.
Eigen::Matrix4d Frustum(double aspect, double near_plane, double far_plane) {
  const double t = near_plane * std::tan(0.5 * 35.0 * M_PI / 180.0), r = t * aspect;
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m(0, 0) = near_plane / r;
  m(1, 1) = near_plane / t;
  m(2, 2) = -(far_plane + near_plane) / (far_plane - near_plane);
  m(2, 3) = -2 * far_plane * near_plane / (far_plane - near_plane);
  m(3, 2) = -1;
  return m;
}

// What glOrtho builds, symmetric across: half-extent `r`, depth [near, far].
Eigen::Matrix4d Ortho(double r, double near_plane, double far_plane) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = 1 / r;
  m(1, 1) = 1 / r;
  m(2, 2) = -2 / (far_plane - near_plane);
  m(2, 3) = -(far_plane + near_plane) / (far_plane - near_plane);
  return m;
}

// A shader's or a program's build status; its log on stderr when it failed (the frame then
// draws nothing with it rather than stopping the station).
template <typename GetStatus, typename GetLog>
void Report(GLuint object, GLenum status, GetStatus get_status, GetLog get_log, const char* what) {
  GLint ok = 0;
  get_status(object, status, &ok);
  if (ok) return;
  char log[2048];
  get_log(object, sizeof log, nullptr, log);
  std::fprintf(stderr, "vsurg render: %s: %s\n", what, log);
}

GLuint Compile(GLenum type, const char* source) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  Report(shader, GL_COMPILE_STATUS, glGetShaderiv, glGetShaderInfoLog, "a shader does not compile");
  return shader;
}

GLuint Link(const char* vertex, const std::string& fragment) {
  const GLuint vs = Compile(GL_VERTEX_SHADER, vertex),
               fs = Compile(GL_FRAGMENT_SHADER, fragment.c_str());
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  Report(program, GL_LINK_STATUS, glGetProgramiv, glGetProgramInfoLog,
         "a shader program does not link");
  glDeleteShader(vs);
  glDeleteShader(fs);
  return program;
}

void SetMatrix(GLuint program, const char* name, const Eigen::Matrix4d& m) {
  const Eigen::Matrix4f f = m.cast<float>();
  glUniformMatrix4fv(glGetUniformLocation(program, name), 1, GL_FALSE, f.data());
}
void SetMatrix3(GLuint program, const char* name, const Eigen::Matrix3d& m) {
  const Eigen::Matrix3f f = m.cast<float>();
  glUniformMatrix3fv(glGetUniformLocation(program, name), 1, GL_FALSE, f.data());
}
void SetVec3(GLuint program, const char* name, const Eigen::Vector3d& v) {
  glUniform3f(glGetUniformLocation(program, name), static_cast<float>(v.x()),
              static_cast<float>(v.y()), static_cast<float>(v.z()));
}
void SetFloat(GLuint program, const char* name, double v) {
  glUniform1f(glGetUniformLocation(program, name), static_cast<float>(v));
}
void SetInt(GLuint program, const char* name, int v) {
  glUniform1i(glGetUniformLocation(program, name), v);
}

// A lit mesh on the GPU: interleaved position, normal, rest position (9 floats a vertex).
struct Part {
  GLuint vao = 0, vbo = 0, ebo = 0;
  GLsizei count = 0;
  // Vertices of 9 floats (position, normal, rest position), or 11 with the tissue's broad
  // detail (tone, vessels) sampled once per vertex.
  void Upload(const std::vector<float>& vertices, const std::vector<uint32_t>& indices,
              GLenum usage, int floats_per_vertex = 9) {
    if (!vao) {
      glGenVertexArrays(1, &vao);
      glGenBuffers(1, &vbo);
      glGenBuffers(1, &ebo);
    }
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(float)),
                 vertices.data(), usage);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(indices.size() * 4),
                 indices.data(), GL_STATIC_DRAW);
    const GLsizei stride = floats_per_vertex * static_cast<GLsizei>(sizeof(float));
    for (GLuint a = 0; a < 3; ++a) {
      glEnableVertexAttribArray(a);
      glVertexAttribPointer(
          a, 3, GL_FLOAT, GL_FALSE, stride,
          reinterpret_cast<const void*>(static_cast<uintptr_t>(a * 3 * sizeof(float))));
    }
    if (floats_per_vertex == 11) {
      glEnableVertexAttribArray(3);
      glVertexAttribPointer(
          3, 2, GL_FLOAT, GL_FALSE, stride,
          reinterpret_cast<const void*>(static_cast<uintptr_t>(9 * sizeof(float))));
    }
    glBindVertexArray(0);
    count = static_cast<GLsizei>(indices.size());
  }
  void Draw() const {
    if (!count) return;
    glBindVertexArray(vao);
    glDrawElements(GL_TRIANGLES, count, GL_UNSIGNED_INT, nullptr);
  }
  void Release() {
    if (vao) glDeleteVertexArrays(1, &vao);
    if (vbo) glDeleteBuffers(1, &vbo);
    if (ebo) glDeleteBuffers(1, &ebo);
    vao = vbo = ebo = 0;
  }
};

std::vector<float> Interleave(const ShapeMesh& m) {
  std::vector<float> out;
  out.reserve(m.positions.size() * 9);
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const auto &p = m.positions[i], &n = m.normals[i];
    out.insert(out.end(), {p.x(), p.y(), p.z(), n.x(), n.y(), n.z(), p.x(), p.y(), p.z()});
  }
  return out;
}

// The detail texture: 64³ texels that tile, RGBA: r a broad tone (value-noise fBm, periods 16
// and 8 texels), g pores (sparse dark spots, period 2–3 texels), b vessels (the ridges of a
// noise of period 11: thin branching lines), a a height (fine fBm minus the pores). Made once
// per process (about 20 ms), uploaded per context.
constexpr int kDetailSize = 64;
const std::vector<unsigned char>& DetailTexels() {
  static const std::vector<unsigned char> texels = [] {
    const int n = kDetailSize;
    std::mt19937 random(20261125);
    std::uniform_real_distribution<float> uniform(0, 1);
    std::vector<float> lattice(static_cast<size_t>(n) * n * n);
    for (float& v : lattice) v = uniform(random);
    // Periodic value noise at `period` texels (period divides n), smoothstep-interpolated.
    const auto noise = [&](float x, float y, float z, int period, int salt) {
      const float step = static_cast<float>(n) / static_cast<float>(period);
      const float fx = x / step, fy = y / step, fz = z / step;
      const int ix = static_cast<int>(std::floor(fx)), iy = static_cast<int>(std::floor(fy)),
                iz = static_cast<int>(std::floor(fz));
      const auto s = [](float t) { return t * t * (3 - 2 * t); };
      const float tx = s(fx - static_cast<float>(ix)), ty = s(fy - static_cast<float>(iy)),
                  tz = s(fz - static_cast<float>(iz));
      const auto at = [&](int a, int b, int c) {
        a = ((a % period) + period) % period;
        b = ((b % period) + period) % period;
        c = ((c % period) + period) % period;
        const size_t k = (static_cast<size_t>(a * 7 + salt) % n) * n * n +
                         (static_cast<size_t>(b * 13 + salt * 3) % n) * n +
                         static_cast<size_t>(c * 29 + salt * 5) % n;
        return lattice[k];
      };
      float v = 0;
      for (int c = 0; c < 2; ++c)
        for (int b = 0; b < 2; ++b)
          for (int a = 0; a < 2; ++a)
            v += (a ? tx : 1 - tx) * (b ? ty : 1 - ty) * (c ? tz : 1 - tz) *
                 at(ix + a, iy + b, iz + c);
      return v;
    };
    std::vector<unsigned char> out(static_cast<size_t>(n) * n * n * 4);
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
          const float fx = static_cast<float>(x), fy = static_cast<float>(y),
                      fz = static_cast<float>(z);
          const float tone = 0.65f * noise(fx, fy, fz, 4, 1) + 0.35f * noise(fx, fy, fz, 8, 2);
          const float pore_noise = noise(fx, fy, fz, 32, 3);
          const float pores = std::clamp((pore_noise - 0.72f) / 0.2f, 0.0f, 1.0f);
          const float ridge = 1 - std::abs(2 * noise(fx, fy, fz, 6, 4) - 1);
          const float ridge2 = 1 - std::abs(2 * noise(fx, fy, fz, 12, 5) - 1);
          const float vessels =
              std::clamp(std::pow(ridge, 14.0f) + 0.6f * std::pow(ridge2, 18.0f), 0.0f, 1.0f);
          const float height = 0.5f + 0.35f * (noise(fx, fy, fz, 16, 6) - 0.5f) +
                               0.25f * (noise(fx, fy, fz, 32, 7) - 0.5f) - 0.35f * pores +
                               0.15f * vessels;
          unsigned char* t = &out[4 * ((static_cast<size_t>(z) * n + y) * n + x)];
          const auto byte = [](float v) {
            return static_cast<unsigned char>(std::clamp(v, 0.0f, 1.0f) * 255 + 0.5f);
          };
          t[0] = byte(tone);
          t[1] = byte(pores);
          t[2] = byte(vessels);
          t[3] = byte(height);
        }
    return out;
  }();
  return texels;
}

// The detail texture sampled on the CPU (trilinear, repeating), at texture coordinates q.
Eigen::Vector4f SampleDetail(const Eigen::Vector3d& q) {
  const std::vector<unsigned char>& t = DetailTexels();
  const int n = kDetailSize;
  Eigen::Vector4f out = Eigen::Vector4f::Zero();
  Eigen::Vector3d x = q * n - Eigen::Vector3d::Constant(0.5);
  const Eigen::Vector3d base = x.array().floor();
  const Eigen::Vector3d f = x - base;
  for (int c = 0; c < 8; ++c) {
    int index[3];
    double weight = 1;
    for (int k = 0; k < 3; ++k) {
      const int bit = (c >> k) & 1;
      index[k] = ((static_cast<int>(base[k]) + bit) % n + n) % n;
      weight *= bit ? f[k] : 1 - f[k];
    }
    const unsigned char* texel =
        &t[4 * ((static_cast<size_t>(index[2]) * n + index[1]) * n + index[0])];
    for (int k = 0; k < 4; ++k) out[k] += static_cast<float>(weight * texel[k] / 255.0);
  }
  return out;
}

struct MaterialLook {
  int shader;
  Eigen::Vector3d albedo;
  double roughness, detail_scale, bump_depth;  // -, repeats per metre, m
};

MaterialLook LookOf(sim::VisualMaterial m) {
  switch (m) {
    case sim::VisualMaterial::kSkin:
      return {shaders::kSkin, {0.66, 0.41, 0.30}, 0.52, 75, 0.00025};
    case sim::VisualMaterial::kOrgan:
      return {shaders::kOrgan, {0.32, 0.075, 0.055}, 0.42, 40, 0.00012};
    case sim::VisualMaterial::kKidney:
      return {shaders::kKidney, {0.20, 0.042, 0.030}, 0.40, 45, 0.00010};
  }
  return {shaders::kSkin, {0.8, 0.56, 0.45}, 0.5, 75, 0.0002};
}

}  // namespace

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
  std::nth_element(sorted.begin(), sorted.begin() + 27, sorted.end());
  const double p90 = sorted[27];
  window_.clear();
  int level = static_cast<int>(level_);
  if (p90 > budget_ms_ && level > 0) {
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

namespace {

// The operating table: a square of drape under the tissue, `half` from its centre along e1 and
// e2 (the plane's axes), its top at the scene's table height.
struct TableFrame {
  Eigen::Vector3d centre, e1, e2;
  double half;
};
TableFrame Table(const Eigen::Vector3d& scene_centre, const Eigen::Vector3d& up, double height,
                 double radius) {
  const Eigen::Vector3d e1 = up.unitOrthogonal();
  return {scene_centre - (scene_centre.dot(up) - height) * up, e1, up.cross(e1), radius * 8};
}

// The polygon on the table that bounds a shadow cast along the key light: its points flattened
// onto the table along the light, and the 16 lines that support them, each pushed out by a
// margin; the polygon's corners are where neighbouring lines meet, counter-clockwise in the
// table's (e1, e2) coordinates. One pass over the points, and around a round shadow within 2.6%
// of the area of their convex hull (16 tan(π/16) / π); a box's corners, as were used before, put
// a corner of drape beside every shadow and the instrument's shadow in a strip ten times its width.
class ShadowBound {
 public:
  static constexpr int kSides = 16;
  ShadowBound(const Eigen::Vector3d& key, const Eigen::Vector3d& up, double table_height,
              const Eigen::Vector3d& e1, const Eigen::Vector3d& e2)
      : key_(key), up_(up), e1_(e1), e2_(e2), height_(table_height), rise_(key.dot(up)) {
    support_.fill(-1e30);
  }
  // A light grazing the table casts no shadow worth drawing on it.
  bool usable() const { return rise_ > 0.05; }
  void Add(const Eigen::Vector3d& p) {
    if (!p.allFinite() || !usable()) return;
    const Eigen::Vector3d d = p - key_ * std::max(p.dot(up_) - height_, 0.0) / rise_;
    const double x = d.dot(e1_), y = d.dot(e2_);
    for (int k = 0; k < kSides; ++k)
      support_[k] = std::max(support_[k], x * Direction(k).x() + y * Direction(k).y());
  }
  bool empty() const { return support_[0] < -1e29; }
  // The corners, in (e1, e2) coordinates relative to the table's frame (not its centre).
  std::vector<Eigen::Vector2d> Corners(double margin) const {
    std::vector<Eigen::Vector2d> corners;
    if (empty()) return corners;
    for (int k = 0; k < kSides; ++k) {
      const int next = (k + 1) % kSides;
      Eigen::Matrix2d lines;
      lines.row(0) = Direction(k).transpose();
      lines.row(1) = Direction(next).transpose();
      corners.push_back(lines.inverse() *
                        Eigen::Vector2d(support_[k] + margin, support_[next] + margin));
    }
    return corners;
  }

 private:
  static Eigen::Vector2d Direction(int k) {
    static const std::array<Eigen::Vector2d, kSides> directions = [] {
      std::array<Eigen::Vector2d, kSides> d;
      for (int i = 0; i < kSides; ++i)
        d[i] = {std::cos(2 * std::numbers::pi * i / kSides),
                std::sin(2 * std::numbers::pi * i / kSides)};
      return d;
    }();
    return directions[k];
  }
  Eigen::Vector3d key_, up_, e1_, e2_;
  double height_, rise_;
  std::array<double, kSides> support_{};
};

}  // namespace

struct MeshView::Gpu {
  GLuint shadow = 0, flat = 0;
  // The lit surfaces' program per variant: material, shadow taps, detail, ambient occlusion,
  // albedo only (compiled when first drawn with).
  std::map<std::array<int, 5>, GLuint> scene;
  GLuint Scene(int material, int shadow_taps, bool with_detail, bool ao, bool albedo_only) {
    const std::array<int, 5> key = {material, shadow_taps, with_detail, ao, albedo_only};
    auto it = scene.find(key);
    if (it != scene.end()) return it->second;
    char defines[200];
    std::snprintf(defines, sizeof defines,
                  "#version 330 core\n#define MATERIAL %d\n#define SHADOW_TAPS %d\n"
                  "#define DETAIL %d\n#define AO %d\n#define ALBEDO_ONLY %d\n",
                  material, shadow_taps, with_detail ? 1 : 0, ao ? 1 : 0, albedo_only ? 1 : 0);
    const std::string common = defines + std::string(shaders::kSceneCommon);
    const GLuint program =
        Link((common + shaders::kSceneVertex).c_str(), common + shaders::kSceneFragment);
    scene.emplace(key, program);
    return program;
  }
  Part tissue, table, steel, handle, jaw;
  Part catcher;  // the polygons on the table that its shadows can fall in, made every frame
  InstrumentParts instrument;
  GLuint flat_vao = 0, flat_vbo = 0;
  GLuint detail = 0;
  GLuint shadow_fbo = 0, shadow_map = 0;
  int shadow_size = 0;
  // The shadow map's texels the last pass wrote (x0, y0, x1, y1; empty when none): the next pass
  // clears them with its own, and nothing outside them.
  std::array<int, 4> shadow_written{};
  // The tissue's own depth as the last pass that drew it left the map (a texture of the map's
  // size and format), over `tissue_written` (empty: none kept). A pass in which only the tool
  // moved copies it back instead of drawing the tissue again: outside a grasp the tool moves in
  // most frames and the tissue in few, and the tissue's casters were about two thirds of a pass.
  GLuint tissue_depth = 0;
  std::array<int, 4> tissue_written{};
  GLuint far_depth = 0;  // the map's size and format, every texel at the far plane: the clear
  // The background (the table and its drape, as they look while the camera, the frame's size and
  // the quality stay), drawn once and copied into every frame.
  GLuint background_fbo = 0, background_colour = 0, background_depth = 0;
  std::array<double, 9> background_key{};  // width, height, quality, eye, centre
  std::array<double, 34> shadow_key{};     // the tool's pose, its jaws, the quality, the light
  std::vector<float> upload;               // the tissue's interleaved vertices, reused every frame
  std::vector<uint32_t> indices;
  // What casts the tissue's shadow at high: the physics surface as moved (positions only), its
  // faces turned away from the light (`caster_cull` culls the others). A fraction of the visual
  // surface's triangles, and the far side of a closed surface is never close enough in depth to
  // the lit side it shades to speckle it, however the fine surface sits over the coarse one.
  // Without a closed, consistently wound physics surface of at least kMinCasterTriangles the
  // visual surface's lit side casts. (Casting the lit side of the arm's coarse skin instead, with
  // half the physics surface's triangles, speckled its lower edge along the terminator.) Below
  // high the drawn coarse surface's own far side casts: fewer triangles still, and it is the
  // surface the shadow falls on.
  GLuint caster_vao = 0, caster_vbo = 0, caster_ebo = 0;
  GLsizei caster_count = 0;
  GLenum caster_cull = GL_FRONT;
  std::vector<float> caster_upload;
  FlatMesh marks;
  // Where the tissue, as last moved, can cast (MeshView::Draw): its box, and the polygon on the
  // table its shadow falls within (ShadowBound's corners; empty: none).
  bool tissue_bounds_stale = true;
  Eigen::Vector3d tissue_lo = Eigen::Vector3d::Zero(), tissue_hi = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector2d> tissue_shadow;

  ~Gpu() {
    for (Part* p : {&tissue, &table, &steel, &handle, &jaw}) p->Release();
    for (const auto& [key, program] : scene) glDeleteProgram(program);
    for (GLuint program : {shadow, flat})
      if (program) glDeleteProgram(program);
    if (flat_vao) glDeleteVertexArrays(1, &flat_vao);
    if (flat_vbo) glDeleteBuffers(1, &flat_vbo);
    if (caster_vao) glDeleteVertexArrays(1, &caster_vao);
    for (GLuint b : {caster_vbo, caster_ebo})
      if (b) glDeleteBuffers(1, &b);
    if (detail) glDeleteTextures(1, &detail);
    if (shadow_map) glDeleteTextures(1, &shadow_map);
    for (GLuint t : {tissue_depth, far_depth})
      if (t) glDeleteTextures(1, &t);
    if (shadow_fbo) glDeleteFramebuffers(1, &shadow_fbo);
    if (background_fbo) glDeleteFramebuffers(1, &background_fbo);
    if (background_colour) glDeleteRenderbuffers(1, &background_colour);
    if (background_depth) glDeleteRenderbuffers(1, &background_depth);
  }

  void EnsureShadowMap(int size) {
    if (shadow_size == size) return;
    if (!shadow_map) {
      glGenTextures(1, &shadow_map);
      glGenFramebuffers(1, &shadow_fbo);
    }
    glBindTexture(GL_TEXTURE_2D, shadow_map);
    // 16-bit depth: half the bytes of 24 (stored in 32) to clear and to read, and over the light's
    // box (some 10 scene radii deep) a step of about 25 µm for the arm, under the polygon offset.
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT16, size, size, 0, GL_DEPTH_COMPONENT,
                 GL_UNSIGNED_SHORT, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    GLint previous = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
    glBindFramebuffer(GL_FRAMEBUFFER, shadow_fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, shadow_map, 0);
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
    glClear(GL_DEPTH_BUFFER_BIT);  // the whole map once; each pass then clears what it wrote
    glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(previous));
    const std::vector<uint16_t> far(static_cast<size_t>(size) * size, 0xFFFF);
    for (GLuint* texture : {&tissue_depth, &far_depth}) {
      if (!*texture) glGenTextures(1, texture);
      glBindTexture(GL_TEXTURE_2D, *texture);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT16, size, size, 0, GL_DEPTH_COMPONENT,
                   GL_UNSIGNED_SHORT, texture == &far_depth ? far.data() : nullptr);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);  // complete: one level
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    shadow_size = size;
    shadow_written = {};
    tissue_written = {};
  }
};

MeshView::MeshView(const geometry::TriMesh& physics, sim::VisualModel visual)
    : rest_(physics), positions_(physics.positions), visual_(std::move(visual)), moved_(physics) {
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
  dirty_ = dirty_ || applied > 0;
  return applied;
}

int MeshView::Apply(const std::vector<int32_t>& indices,
                    const std::vector<geometry::Vec3>& positions) {
  const int applied = ApplyMoved(positions_, indices, positions);
  dirty_ = dirty_ || applied > 0;
  return applied;
}

void MeshView::ResetToRest() {
  positions_ = rest_.positions;
  dirty_ = true;
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
  geometry::ComputeVertexNormals(moved_);
  visual_.mapping.Apply(moved_.positions, moved_.normals, fine_);
  geometry::VertexNormals(visual_.surface.triangles, fine_, fine_normals_, world_up_.cast<float>());
  dirty_ = false;
}

void MeshView::Draw(int width, int height, const Overlay& overlay) {
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
  const size_t fine_count = visual_.surface.positions.size();
  if (first) {
    g.shadow = Link(shaders::kShadowVertex, shaders::kShadowFragment);
    g.flat = Link(shaders::kFlatVertex, shaders::kFlatFragment);
  }
  if (remake_tissue) {
    // The tissue: rest positions fixed, positions and normals rewritten when they move.
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
  if (first) {
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
    g.instrument = MakeInstrument(visual_.instrument);
    g.steel.Upload(Interleave(g.instrument.steel), g.instrument.steel.indices, GL_STATIC_DRAW);
    g.handle.Upload(Interleave(g.instrument.handle), g.instrument.handle.indices, GL_STATIC_DRAW);
    g.jaw.Upload(Interleave(g.instrument.jaw), g.instrument.jaw.indices, GL_STATIC_DRAW);
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
  if (dirty_) {
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

  GLint target = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &target);
  const bool stylus = overlay.show_stylus && overlay.tip.allFinite() &&
                      overlay.orientation.coeffs().allFinite() && !overlay.albedo_only;
  Eigen::Affine3d tool = Eigen::Affine3d::Identity();
  if (stylus) tool = Eigen::Translation3d(overlay.tip) * overlay.orientation.normalized();
  const float open = overlay.grasping ? 0.0f : g.instrument.open_rad;
  const auto jaw_pose = [&](int side) {
    const Eigen::Vector3f hinge = g.instrument.hinge;
    Eigen::Affine3f local = Eigen::Translation3f(hinge) *
                            Eigen::AngleAxisf(side ? -open : open, Eigen::Vector3f::UnitX()) *
                            Eigen::Translation3f(-hinge);
    if (side)
      local = local * Eigen::AngleAxisf(std::numbers::pi_v<float>, Eigen::Vector3f::UnitZ());
    return Eigen::Affine3d(tool.matrix() * local.matrix().cast<double>());
  };
  const Quality q = quality_;
  const bool shadows = q != Quality::kLow && !overlay.albedo_only;
  const Eigen::Matrix4d light = LightViewProjection();
  // What casts shadows, as boxes' corners: the tissue's (its drawn and its physics surface) and
  // the instrument's (in its own frame ±5 cm across, from 1 cm below the tip to 21 cm above,
  // around every instrument's parts and open jaws). The shadow pass draws and the table's shadows
  // are shaded only where these can fall; without shadows neither is made.
  std::vector<Eigen::Vector3d> tissue_box, tool_box;
  if (shadows) {
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
      tissue_box.emplace_back(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(),
                              c & 4 ? hi.z() : lo.z());
      if (stylus)
        tool_box.push_back(tool * Eigen::Vector3d(c & 1 ? 0.05 : -0.05, c & 2 ? 0.05 : -0.05,
                                                  c & 4 ? 0.21 : -0.01));
    }
  }

  // 1. The shadow map: depth from the key light of the tissue and the instrument; drawn again
  // only when one of them or the light moved (a trainee holding still costs no shadow pass).
  std::array<double, 34> shadow_key{};
  {
    const Eigen::Matrix4d pose = stylus ? tool.matrix() : Eigen::Matrix4d::Zero();
    std::copy(pose.data(), pose.data() + 16, shadow_key.begin());
    shadow_key[16] = open;
    shadow_key[17] = static_cast<double>(q);
    std::copy(light.data(), light.data() + 16, shadow_key.begin() + 18);
  }
  if (shadows && (moved_since_shadow_ || shadow_key != g.shadow_key)) {
    // The tissue's casters are drawn again when it or the light moved (SetCamera moves the light
    // with the centre), else its kept depth is copied back (below).
    const bool tissue_moved =
        moved_since_shadow_ ||
        !std::equal(shadow_key.begin() + 18, shadow_key.end(), g.shadow_key.begin() + 18);
    moved_since_shadow_ = false;
    g.shadow_key = shadow_key;
    const int size = q == Quality::kHigh ? 2048 : 1024;
    g.EnsureShadowMap(size);
    glBindFramebuffer(GL_FRAMEBUFFER, g.shadow_fbo);
    glViewport(0, 0, size, size);
    // Only the texels the casters can cover are cleared and drawn, with those the last pass wrote
    // (the rest still hold the first clear): the tissue's box and the tool's, projected along the
    // light, widened by two texels. A software renderer clears and rasterises per 64² tile, and
    // the casters cover a third of the map or less. The clear is a copy from a map kept at the
    // far plane (Gpu::far_depth): on llvmpipe a depth clear, scissored or whole, took 0.4-0.5 ms
    // of a moving frame at medium and the copy 0.01 ms.
    const auto texels = [&](const std::vector<Eigen::Vector3d>& box) {
      std::array<int, 4> r{size, size, 0, 0};  // x0, y0, x1, y1
      for (const Eigen::Vector3d& p : box) {
        const Eigen::Vector4d clip = light * p.homogeneous();
        if (!clip.allFinite()) return std::array<int, 4>{0, 0, size, size};
        for (int axis = 0; axis < 2; ++axis) {
          const double t = std::clamp((clip[axis] / clip.w() + 1) * 0.5 * size, -1.0, size + 1.0);
          r[axis] = std::min(r[axis], static_cast<int>(std::floor(t)) - 2);
          r[axis + 2] = std::max(r[axis + 2], static_cast<int>(std::ceil(t)) + 2);
        }
      }
      for (int& edge : r) edge = std::clamp(edge, 0, size);
      return r;
    };
    const std::array<int, 4> tissue_rect = texels(tissue_box), tool_rect = texels(tool_box);
    const auto none = [](const std::array<int, 4>& r) { return r[2] <= r[0] || r[3] <= r[1]; };
    const auto unite = [&](std::array<int, 4> a, const std::array<int, 4>& b) {
      if (none(b)) return a;
      for (int k : {0, 1}) a[k] = std::min(a[k], b[k]);
      for (int k : {2, 3}) a[k] = std::max(a[k], b[k]);
      return a;
    };
    const std::array<int, 4> rect = unite(tissue_rect, tool_rect);
    const std::array<int, 4> clear = unite(rect, g.shadow_written);
    g.shadow_written = rect;
    const auto copy = [&](GLuint from, GLuint to, const std::array<int, 4>& r) {
      if (none(r)) return;
      glCopyImageSubData(from, GL_TEXTURE_2D, 0, r[0], r[1], 0, to, GL_TEXTURE_2D, 0, r[0], r[1], 0,
                         r[2] - r[0], r[3] - r[1], 1);
    };
    copy(g.far_depth, g.shadow_map, clear);
    glEnable(GL_SCISSOR_TEST);
    glScissor(clear[0], clear[1], std::max(clear[2] - clear[0], 0),
              std::max(clear[3] - clear[1], 0));
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.5f, 2.0f);
    glUseProgram(g.shadow);
    SetMatrix(g.shadow, "uLightViewProj", light);
    SetMatrix(g.shadow, "uModel", Eigen::Matrix4d::Identity());
    // The tissue: its depth as the last pass that drew it left it when neither it nor the light
    // moved since (a copy of a third of the map or less, against rasterising its casters), else
    // drawn and kept for the passes after.
    if (!tissue_moved && !none(tissue_rect) && g.tissue_written == tissue_rect) {
      copy(g.tissue_depth, g.shadow_map, tissue_rect);
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
        g.tissue.Draw();
      }
      glDisable(GL_CULL_FACE);
      g.tissue_written = {};
      if (!none(tissue_rect)) {
        copy(g.shadow_map, g.tissue_depth, tissue_rect);
        g.tissue_written = tissue_rect;
      }
    }
    if (stylus) {
      SetMatrix(g.shadow, "uModel", tool.matrix());
      g.steel.Draw();
      g.handle.Draw();
      if (g.instrument.has_jaws)
        for (int side = 0; side < 2; ++side) {
          SetMatrix(g.shadow, "uModel", jaw_pose(side).matrix());
          g.jaw.Draw();
        }
    }
    glDisable(GL_POLYGON_OFFSET_FILL);
    glDisable(GL_SCISSOR_TEST);
    glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
  }

  // 2. The scene.
  glViewport(0, 0, width, height);
  glEnable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  const Eigen::Matrix4d view_projection = Projection(width, height) * View();
  const int taps = shadows ? (q == Quality::kHigh ? 4 : 1) : 0;
  const bool detail = q == Quality::kHigh || overlay.albedo_only, ao = q == Quality::kHigh;
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, shadows ? g.shadow_map : 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_3D, g.detail);
  glActiveTexture(GL_TEXTURE0);
  const Eigen::Vector3d fill = ((eye_ - centre_).normalized() - 0.3 * world_up_).normalized();
  const auto draw_part = [&](const Part& part, const Eigen::Affine3d& pose, int material,
                             const Eigen::Vector3d& albedo, double roughness, double scale,
                             double bump, int part_taps) {
    const GLuint s = g.Scene(material, part_taps, detail && scale > 1, ao, overlay.albedo_only);
    glUseProgram(s);
    SetMatrix(s, "uViewProj", view_projection);
    SetMatrix(s, "uLightViewProj", light);
    SetVec3(s, "uEye", eye_);
    SetVec3(s, "uKeyDir", key_dir_);
    SetVec3(s, "uKeyColour", Eigen::Vector3d(1.36, 1.27, 1.14));
    SetVec3(s, "uFillDir", fill);
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
  };
  const Eigen::Vector3d drape(0.035, 0.15, 0.17);
  if (overlay.albedo_only) {
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  } else {
    // The background: drawn again only when what it shows changed, else copied.
    const std::array<double, 9> key = {double(width), double(height), double(q),
                                       eye_.x(),      eye_.y(),       eye_.z(),
                                       centre_.x(),   centre_.y(),    centre_.z()};
    if (!g.background_fbo) {
      glGenFramebuffers(1, &g.background_fbo);
      glGenRenderbuffers(1, &g.background_colour);
      glGenRenderbuffers(1, &g.background_depth);
    }
    if (key != g.background_key) {
      glBindRenderbuffer(GL_RENDERBUFFER, g.background_colour);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
      glBindRenderbuffer(GL_RENDERBUFFER, g.background_depth);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
      glBindFramebuffer(GL_FRAMEBUFFER, g.background_fbo);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                g.background_colour);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                                g.background_depth);
      glClearColor(0.10f, 0.11f, 0.13f, 1.0f);
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      draw_part(g.table, Eigen::Affine3d::Identity(), shaders::kDrape, drape, 0.85, 220, 0.0004, 0);
      glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
      g.background_key = key;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, g.background_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, static_cast<GLuint>(target));
    glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
    glClear(GL_DEPTH_BUFFER_BIT);
  }
  // The instrument first: it is nearer than the tissue where they overlap, so the tissue's
  // pixels behind it fail the depth test before they are shaded.
  if (stylus && !overlay.albedo_only) {
    const Eigen::Vector3d steel(0.78, 0.78, 0.80);
    draw_part(g.steel, tool, shaders::kMetal, steel, 0.28, 1, 0, taps);
    draw_part(g.handle, tool, shaders::kPlastic, Eigen::Vector3d(0.035, 0.04, 0.05), 0.45, 1, 0,
              taps);
    if (g.instrument.has_jaws)
      for (int side = 0; side < 2; ++side)
        draw_part(g.jaw, jaw_pose(side), shaders::kMetal, Eigen::Vector3d(0.70, 0.71, 0.73), 0.38,
                  1, 0, taps);
  }
  const MaterialLook look = LookOf(visual_.material);
  // The visual surface is closed and wound outward (tested): its back half is culled, which on a
  // software renderer halves the triangles set up.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  draw_part(g.tissue, Eigen::Affine3d::Identity(), look.shader, look.albedo, look.roughness,
            look.detail_scale, look.bump_depth, taps);
  glDisable(GL_CULL_FACE);
  if (!overlay.albedo_only) {
    // The shadows on the table: blended over the background's table, only where the tissue's
    // and the tool's shadows can fall (the table covers most of the frame; shading all of it for
    // a shadow a fifth its size is what cost the most).
    if (shadows) {
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
      add_catcher(catchers_cover_table_ && !stylus ? table : g.tissue_shadow, 0.0005);
      if (stylus) {
        ShadowBound bound(key_dir_, world_up_, visual_.table_height, t.e1, t.e2);
        const auto add = [&](const ShapeMesh& part, const Eigen::Affine3d& pose) {
          for (const Eigen::Vector3f& p : part.positions) bound.Add(pose * p.cast<double>());
        };
        add(g.instrument.steel, tool);
        add(g.instrument.handle, tool);
        if (g.instrument.has_jaws)
          for (int side = 0; side < 2; ++side) add(g.instrument.jaw, jaw_pose(side));
        add_catcher(catchers_cover_table_ ? table : bound.Corners(radius_ * 0.03), 0.0006);
      }
      if (!catcher.indices.empty()) {
        g.catcher.Upload(Interleave(catcher), catcher.indices, GL_STREAM_DRAW);
        glEnable(GL_BLEND);
        glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
        draw_part(g.catcher, Eigen::Affine3d::Identity(), shaders::kShadowCatcher, drape, 1, 1, 0,
                  taps);
        glDisable(GL_BLEND);
      }
    }

    // 3. Guidance marks, unlit: the twist target's band and the twist so far as arcs, the force
    // on the hand as an arrow.
    g.marks.Clear();
    const Guidance& gd = overlay.guidance;
    if (gd.show && gd.twist && visual_.twist_radius > 0) {
      const bool at_tool = visual_.instrument == sim::Instrument::kGrasper;
      if (!at_tool || stylus) {
        const Eigen::Vector3d centre =
            at_tool ? Eigen::Vector3d(overlay.tip + 0.004 * world_up_) : visual_.twist_centre;
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
    if (stylus && overlay.force.allFinite() && overlay.force.norm() > 0.05) {
      const Eigen::Vector3d head = overlay.tip + 0.02 * overlay.force;
      const Eigen::Vector3d neck = overlay.tip + 0.75 * (head - overlay.tip);
      const Eigen::Vector4f yellow(1.0f, 0.86f, 0.15f, 0.9f);
      g.marks.Tube(overlay.tip, neck, 0.0008, yellow);
      g.marks.Cone(neck, head, 0.0022, yellow);
    }
    if (g.marks.vertices() > 0) {
      glEnable(GL_BLEND);
      glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
      glDepthMask(GL_FALSE);
      glUseProgram(g.flat);
      SetMatrix(g.flat, "uViewProj", view_projection);
      glBindVertexArray(g.flat_vao);
      glBindBuffer(GL_ARRAY_BUFFER, g.flat_vbo);
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.marks.data.size() * sizeof(float)),
                   g.marks.data.data(), GL_STREAM_DRAW);
      glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(g.marks.vertices()));
      glDepthMask(GL_TRUE);
      glDisable(GL_BLEND);
    }
  }
  glBindVertexArray(0);
  glUseProgram(0);

  // 4. The HUD.
  if (!overlay.albedo_only &&
      (!overlay.hud.empty() || overlay.guidance.show || overlay.summary.show)) {
    if (!hud_) hud_ = std::make_unique<Hud>();
    hud_->Draw(width, height, overlay.hud, overlay.guidance, overlay.summary);
  }
}

}  // namespace vsurg::client
