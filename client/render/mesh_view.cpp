#include "client/render/mesh_view.h"

#include <imgui.h>
#include <imgui_impl_opengl2.h>

#include <GL/gl.h>

#include <algorithm>
#include <array>
#include <cmath>

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

}  // namespace

MeshView::MeshView(const geometry::TriMesh& rest) : rest_(rest), positions_(rest.positions) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = -lo;
  for (const auto& p : rest_.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  if (rest_.positions.empty()) lo = hi = Eigen::Vector3d::Zero();
  centre_ = 0.5 * (lo + hi);
  radius_ = std::max(0.5 * (hi - lo).norm(), 1e-3);
  // Longest extent across the screen; "up" the next longest; look along the shortest, raised.
  const Eigen::Vector3d extent = hi - lo;
  int axes[3] = {0, 1, 2};
  std::sort(axes, axes + 3, [&](int a, int b) { return extent[a] > extent[b]; });
  Eigen::Vector3d across = Eigen::Vector3d::Unit(axes[0]);
  up_ = Eigen::Vector3d::Unit(axes[1]);
  if (extent[axes[0]] < 1.5 * extent[axes[2]]) up_ = Eigen::Vector3d::UnitZ();  // round: z up
  if (std::abs(up_.dot(across)) > 0.9) across = up_.unitOrthogonal();
  const Eigen::Vector3d view = up_.cross(across).normalized();
  eye_ = centre_ + radius_ * 2.4 * (view + 0.45 * up_).normalized();
  // A checker in cylindrical coordinates about the long axis (a sphere: about z), painted at
  // rest as texture coordinates: 12 sectors around (30°: the 45° task twist shows as a half-cell
  // shift), 2 cm along. A 2×2 texture, nearest-sampled and repeated, gives crisp cell edges
  // wherever they fall between vertices.
  const Eigen::Vector3d axis = extent[axes[0]] < 1.5 * extent[axes[2]]
                                   ? Eigen::Vector3d::UnitZ()
                                   : Eigen::Vector3d::Unit(axes[0]);
  const Eigen::Vector3d e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  constexpr double kSectors = 12, kCell = 0.02;  // sectors around, m along
  std::vector<std::array<float, 2>> uv(rest_.positions.size());
  for (size_t i = 0; i < rest_.positions.size(); ++i) {
    const Eigen::Vector3d d = rest_.positions[i] - centre_;
    const double angle = std::atan2(d.dot(e2), d.dot(e1)) + M_PI;  // 0..2π
    // Texture cells are 2×2 checker squares: half a texture unit per sector or ring.
    uv[i] = {static_cast<float>(angle / (2 * M_PI) * kSectors / 2),
             static_cast<float>(d.dot(axis) / kCell / 2)};
  }
  // Triangles across the angle's seam (u from about kSectors/2 back to 0) take copies of their
  // low-u vertices with u one turn on, so no triangle stretches over the whole texture.
  std::vector<int> copy_of(rest_.positions.size(), -1);
  render_vertex_.resize(rest_.positions.size());
  for (size_t i = 0; i < render_vertex_.size(); ++i) render_vertex_[i] = static_cast<int>(i);
  tex_coords_.clear();
  for (const auto& t : uv) tex_coords_.insert(tex_coords_.end(), {t[0], t[1]});
  const float turn = static_cast<float>(kSectors / 2);
  indices_.reserve(rest_.triangles.size() * 3);
  for (const auto& t : rest_.triangles) {
    const float u_min = std::min({uv[t[0]][0], uv[t[1]][0], uv[t[2]][0]});
    const float u_max = std::max({uv[t[0]][0], uv[t[1]][0], uv[t[2]][0]});
    const bool seam = u_max - u_min > turn / 2;
    for (int v : t) {
      int r = v;
      if (seam && uv[v][0] < turn / 2) {
        if (copy_of[v] < 0) {
          copy_of[v] = static_cast<int>(render_vertex_.size());
          render_vertex_.push_back(v);
          tex_coords_.insert(tex_coords_.end(), {uv[v][0] + turn, uv[v][1]});
        }
        r = copy_of[v];
      }
      indices_.push_back(static_cast<unsigned int>(r));
    }
  }
  vertex_buffer_.resize(render_vertex_.size() * 3);
  normal_buffer_.resize(render_vertex_.size() * 3);
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
  return ApplyMoved(positions_, indices, positions);
}

int MeshView::Apply(const std::vector<int32_t>& indices,
                    const std::vector<geometry::Vec3>& positions) {
  return ApplyMoved(positions_, indices, positions);
}

Eigen::Matrix4d MeshView::Projection(int width, int height) const {
  return Frustum(static_cast<double>(width) / std::max(height, 1), radius_ * 0.1, radius_ * 10);
}

Eigen::Matrix4d MeshView::View() const {
  return LookAt(eye_, centre_, up_);
}

Eigen::Vector2d MeshView::Project(const geometry::Vec3& p, int width, int height) const {
  const Eigen::Vector4d clip = Projection(width, height) * View() * p.homogeneous();
  const Eigen::Vector2d ndc = clip.head<2>() / clip.w();
  return {(ndc.x() + 1) * 0.5 * width, (1 - ndc.y()) * 0.5 * height};
}

void MeshView::ResetToRest() {
  positions_ = rest_.positions;
}

void MeshView::ComputeNormals() {
  std::vector<Eigen::Vector3d> normals(positions_.size(), Eigen::Vector3d::Zero());
  for (const auto& t : rest_.triangles) {
    // Area-weighted: the cross product's length is twice the triangle's area.
    const Eigen::Vector3d n =
        (positions_[t[1]] - positions_[t[0]]).cross(positions_[t[2]] - positions_[t[0]]);
    for (int v : t) normals[v] += n;
  }
  for (size_t r = 0; r < render_vertex_.size(); ++r) {
    const int i = render_vertex_[r];
    const double length = normals[i].norm();
    const Eigen::Vector3d n = length > 0 ? Eigen::Vector3d(normals[i] / length) : up_;
    for (int k = 0; k < 3; ++k) {
      vertex_buffer_[3 * r + k] = static_cast<float>(positions_[i][k]);
      normal_buffer_[3 * r + k] = static_cast<float>(n[k]);
    }
  }
}

void MeshView::Draw(int width, int height, const Overlay& overlay) {
  glViewport(0, 0, width, height);
  glClearColor(0.13f, 0.15f, 0.19f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);

  const Eigen::Matrix4d projection = Projection(width, height), view = View();
  glMatrixMode(GL_PROJECTION);
  glLoadMatrixd(projection.data());
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(view.data());

  // A head light and a fill light, in eye coordinates, set after the view is loaded.
  glEnable(GL_LIGHTING);
  glEnable(GL_LIGHT0);
  glEnable(GL_LIGHT1);
  glEnable(GL_NORMALIZE);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  const Eigen::Vector3f key_dir = (eye_ - centre_ + radius_ * up_).cast<float>().normalized();
  const GLfloat key[] = {key_dir.x(), key_dir.y(), key_dir.z(), 0.0f};
  const GLfloat key_colour[] = {0.85f, 0.85f, 0.85f, 1.0f};
  const GLfloat fill[] = {static_cast<GLfloat>(-up_.x()), static_cast<GLfloat>(-up_.y()),
                          static_cast<GLfloat>(-up_.z()), 0.0f};
  const GLfloat fill_colour[] = {0.25f, 0.25f, 0.3f, 1.0f};
  const GLfloat ambient[] = {0.25f, 0.25f, 0.25f, 1.0f};
  glLightfv(GL_LIGHT0, GL_POSITION, key);
  glLightfv(GL_LIGHT0, GL_DIFFUSE, key_colour);
  glLightfv(GL_LIGHT1, GL_POSITION, fill);
  glLightfv(GL_LIGHT1, GL_DIFFUSE, fill_colour);
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
  glEnable(GL_COLOR_MATERIAL);
  glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
  glShadeModel(GL_SMOOTH);

  if (texture_ == 0) {
    // Two skin tones in a 2×2 checker; the lit white material modulates it.
    const unsigned char texels[] = {236, 178, 150, 176, 104, 92, 176, 104, 92, 236, 178, 150};
    glGenTextures(1, &texture_);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, 2, 2, 0, GL_RGB, GL_UNSIGNED_BYTE, texels);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  }
  glEnable(GL_TEXTURE_2D);
  glBindTexture(GL_TEXTURE_2D, texture_);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  glColor3f(1.0f, 1.0f, 1.0f);

  ComputeNormals();
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_NORMAL_ARRAY);
  glEnableClientState(GL_TEXTURE_COORD_ARRAY);
  glVertexPointer(3, GL_FLOAT, 0, vertex_buffer_.data());
  glNormalPointer(GL_FLOAT, 0, normal_buffer_.data());
  glTexCoordPointer(2, GL_FLOAT, 0, tex_coords_.data());
  glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices_.size()), GL_UNSIGNED_INT,
                 indices_.data());
  glDisableClientState(GL_TEXTURE_COORD_ARRAY);
  glDisableClientState(GL_NORMAL_ARRAY);
  glDisableClientState(GL_VERTEX_ARRAY);
  glDisable(GL_TEXTURE_2D);
  glDisable(GL_LIGHTING);

  if (overlay.show_stylus && overlay.tip.allFinite()) {
    // The stylus: a shaft 8 cm back along its own z axis, the tip a dot (green in contact,
    // orange while grasping); the force on the hand from the tip, yellow, 2 cm per newton.
    const Eigen::Vector3d back = overlay.tip + overlay.orientation * Eigen::Vector3d(0, 0, 0.08);
    glLineWidth(4.0f);
    glColor3f(0.75f, 0.78f, 0.85f);
    glBegin(GL_LINES);
    glVertex3dv(overlay.tip.data());
    glVertex3dv(back.data());
    glEnd();
    glPointSize(9.0f);
    if (overlay.grasping)
      glColor3f(1.0f, 0.55f, 0.1f);
    else if (overlay.contact)
      glColor3f(0.2f, 0.9f, 0.3f);
    else
      glColor3f(0.3f, 0.6f, 1.0f);
    glBegin(GL_POINTS);
    glVertex3dv(overlay.tip.data());
    glEnd();
    if (overlay.force.allFinite() && overlay.force.norm() > 1e-3) {
      const Eigen::Vector3d head = overlay.tip + 0.02 * overlay.force;
      glLineWidth(3.0f);
      glColor3f(1.0f, 0.9f, 0.1f);
      glBegin(GL_LINES);
      glVertex3dv(overlay.tip.data());
      glVertex3dv(head.data());
      glEnd();
    }
  }

  if (!overlay.hud.empty()) DrawHud(width, height, overlay.hud);
}

// The HUD as an ImGui panel. One ImGui context per view (a view belongs to one GL context); the
// OpenGL 2 backend matches the fixed-function pipeline the scene is drawn with, and restores the
// GL state it changes.
struct MeshView::Hud {
  ImGuiContext* context = nullptr;
  Hud() {
    context = ImGui::CreateContext();
    ImGui::SetCurrentContext(context);
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;  // no imgui.ini written beside the binary
    io.LogFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplOpenGL2_Init();
  }
  ~Hud() {
    ImGui::SetCurrentContext(context);
    ImGui_ImplOpenGL2_Shutdown();
    ImGui::DestroyContext(context);
  }
};

MeshView::~MeshView() = default;

void MeshView::DrawHud(int width, int height, const std::vector<std::string>& lines) {
  if (!hud_) hud_ = std::make_unique<Hud>();
  ImGui::SetCurrentContext(hud_->context);
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(static_cast<float>(width), static_cast<float>(height));
  io.DeltaTime = 1.0f / 60.0f;
  io.FontGlobalScale = height >= 600 ? 1.5f : 1.0f;
  ImGui_ImplOpenGL2_NewFrame();
  ImGui::NewFrame();
  ImGui::SetNextWindowPos(ImVec2(6, 6));
  ImGui::SetNextWindowBgAlpha(0.6f);
  ImGui::Begin("hud", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                   ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoSavedSettings |
                   ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav);
  for (size_t k = 0; k < lines.size(); ++k) {
    if (k == 0) {
      ImGui::TextColored(ImVec4(0.55f, 0.85f, 1.0f, 1.0f), "%s", lines[k].c_str());
      if (lines.size() > 1) ImGui::Separator();
    } else {
      ImGui::TextUnformatted(lines[k].c_str());
    }
  }
  ImGui::End();
  ImGui::Render();
  ImGui_ImplOpenGL2_RenderDrawData(ImGui::GetDrawData());
}

}  // namespace vsurg::client
