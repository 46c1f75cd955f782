// The station view's GL plumbing and the look of what it draws, shared by MeshView's resources
// (mesh_view.cpp) and its passes (mesh_view_draw.cpp): matrices, shader programs and uniforms, a
// lit mesh on the GPU, the tissue's detail texture and materials, the operating table and the
// bound of a shadow on it. Needs a current OpenGL context for the GL calls.
#pragma once

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "client/render/shapes.h"
#include "common/sim/scene.h"

namespace vsurg::client::gl {

// The view matrix looking from `eye` at `centre` (what gluLookAt builds).
Eigen::Matrix4d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& centre,
                       const Eigen::Vector3d& up);

// What glFrustum builds: a 35° vertical field of view.
Eigen::Matrix4d Frustum(double aspect, double near_plane, double far_plane);

// What glOrtho builds, symmetric across: half-extent `r`, depth [near, far].
Eigen::Matrix4d Ortho(double r, double near_plane, double far_plane);

// A shader of `type` compiled, and a program of a vertex and a fragment shader linked; a failure
// is reported on stderr with the driver's log.
GLuint Compile(GLenum type, const char* source);
GLuint Link(const char* vertex, const std::string& fragment);

// Uniforms of `program` by name (the program in use).
void SetMatrix(GLuint program, const char* name, const Eigen::Matrix4d& m);
void SetMatrix3(GLuint program, const char* name, const Eigen::Matrix3d& m);
void SetVec3(GLuint program, const char* name, const Eigen::Vector3d& v);
void SetFloat(GLuint program, const char* name, double v);
void SetInt(GLuint program, const char* name, int v);

// A shape's vertices as a Part takes them: position, normal, and the position again as its rest.
std::vector<float> Interleave(const ShapeMesh& m);

constexpr int kDetailSize = 64;

// The detail texture: 64³ texels that tile, RGBA: r a broad tone (value-noise fBm, periods 16
// and 8 texels), g pores (sparse dark spots, period 2–3 texels), b vessels (the ridges of a
// noise of period 11: thin branching lines), a a height (fine fBm minus the pores). Made once
// per process (about 20 ms), uploaded per context.
const std::vector<unsigned char>& DetailTexels();

// The detail texture sampled on the CPU (trilinear, repeating), at texture coordinates q.
Eigen::Vector4f SampleDetail(const Eigen::Vector3d& q);

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

struct MaterialLook {
  int shader;
  Eigen::Vector3d albedo;
  double roughness, detail_scale, bump_depth;  // -, repeats per metre, m
};
MaterialLook LookOf(sim::VisualMaterial m);

// The operating table: a square of drape under the tissue, `half` from its centre along e1 and
// e2 (the plane's axes), its top at the scene's table height.
struct TableFrame {
  Eigen::Vector3d centre, e1, e2;
  double half;
};

TableFrame Table(const Eigen::Vector3d& scene_centre, const Eigen::Vector3d& up, double height,
                 double radius);

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

}  // namespace vsurg::client::gl
