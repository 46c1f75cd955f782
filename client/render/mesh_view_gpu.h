// MeshView's objects on the GPU (mesh_view.h): programs, the tissue's and the instrument's
// buffers, the shadow map and what its passes keep between frames. Made at the first Draw and
// updated by MeshView::Prepare (mesh_view.cpp); read by the passes (mesh_view_draw.cpp).
#pragma once

#include <array>
#include <map>
#include <vector>

#include "client/render/gl_resources.h"
#include "client/render/mesh_view.h"
#include "client/render/shaders.h"
#include "client/render/shapes.h"

namespace vsurg::client {

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
        gl::Link((common + shaders::kSceneVertex).c_str(), common + shaders::kSceneFragment);
    scene.emplace(key, program);
    return program;
  }
  gl::Part tissue, table;
  gl::Part catcher;  // the polygons on the table that its shadows can fall in, made every frame
  gl::Part walls;    // a cut sheet's walls (cut_walls.h), made again when the tissue moves
  ShapeMesh wall_mesh;
  // The instruments: the first hand's, and the second hand's when the scene has one (`made`).
  struct Tool {
    InstrumentParts shape;
    gl::Part steel, handle, jaw;
    bool made = false;
  };
  std::array<Tool, 2> tools;
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
  // Both tools' poses and jaws (17 each), the quality, the light (16: the last).
  std::array<double, 51> shadow_key{};
  std::vector<float> upload;  // the tissue's interleaved vertices, reused every frame
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
  // table its shadow falls within (gl::ShadowBound's corners; empty: none).
  bool tissue_bounds_stale = true;
  Eigen::Vector3d tissue_lo = Eigen::Vector3d::Zero(), tissue_hi = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector2d> tissue_shadow;

  ~Gpu() {
    for (gl::Part* p : {&tissue, &table, &walls}) p->Release();
    for (Tool& t : tools)
      for (gl::Part* p : {&t.steel, &t.handle, &t.jaw}) p->Release();
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

}  // namespace vsurg::client
