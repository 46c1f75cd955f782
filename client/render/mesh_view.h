// Draws a session's tissue as the trainee and the instructor see it: the deformed surface,
// smooth-shaded, with a checker of sectors and rings painted on it at rest (a surface of
// revolution twisted about its own axis would otherwise look unchanged), the stylus, the force
// vector and a HUD panel (Dear ImGui, drawn by its OpenGL 2 backend over the scene).
//
// Units: positions in metres in the scene frame; force in newtons (drawn 2 cm per newton).
// Threads: the render thread that owns the current OpenGL context (one context per MeshView:
// the checker texture is made in the first one drawn with).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry/mesh.h"

namespace vsurg::client {

struct Overlay {
  bool show_stylus = false;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();  // m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N, drawn from the tip
  bool grasping = false, contact = false;
  std::vector<std::string> hud;  // the panel's lines, top left: a title line, then the figures
};

class MeshView {
 public:
  // The camera is fitted to the rest mesh: its longest extent across the view, seen from the
  // side and a little above.
  explicit MeshView(const geometry::TriMesh& rest);
  ~MeshView();  // with its context current, as for Draw
  MeshView(const MeshView&) = delete;
  MeshView& operator=(const MeshView&) = delete;

  // Vertices that moved (as a SceneFrame or a monitor's telemetry carries them); indices out of
  // range and non-finite positions are ignored. Returns how many were applied.
  int Apply(const std::vector<int32_t>& indices, const std::vector<Eigen::Vector3f>& positions);
  int Apply(const std::vector<int32_t>& indices, const std::vector<geometry::Vec3>& positions);
  void ResetToRest();
  const std::vector<geometry::Vec3>& positions() const { return positions_; }

  // Where a scene point lands in a width × height image (pixels, y down).
  Eigen::Vector2d Project(const geometry::Vec3& p, int width, int height) const;

  // Clears and draws the whole frame into the current context's framebuffer.
  void Draw(int width, int height, const Overlay& overlay);

 private:
  void ComputeNormals();
  Eigen::Matrix4d Projection(int width, int height) const;
  Eigen::Matrix4d View() const;

  geometry::TriMesh rest_;
  std::vector<geometry::Vec3> positions_;
  // What is drawn: mesh vertices plus copies along the checker's seam (render_vertex_ maps each
  // drawn vertex to its mesh vertex), with their texture coordinates.
  std::vector<int> render_vertex_;
  std::vector<float> vertex_buffer_, normal_buffer_, tex_coords_;
  std::vector<unsigned int> indices_;
  unsigned int texture_ = 0;  // the checker, made at the first Draw (needs the context)
  struct Hud;                 // the panel's ImGui context, made at the first Draw with a HUD
  std::unique_ptr<Hud> hud_;
  void DrawHud(int width, int height, const std::vector<std::string>& lines);
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero(), eye_ = Eigen::Vector3d::UnitY(),
                  up_ = Eigen::Vector3d::UnitZ();
  double radius_ = 0.1;
};

}  // namespace vsurg::client
