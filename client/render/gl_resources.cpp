#include "client/render/gl_resources.h"

#include <algorithm>
#include <cstdio>
#include <random>

#include "client/render/shaders.h"

namespace vsurg::client::gl {

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
namespace {

template <typename GetStatus, typename GetLog>
void Report(GLuint object, GLenum status, GetStatus get_status, GetLog get_log, const char* what) {
  GLint ok = 0;
  get_status(object, status, &ok);
  if (ok) return;
  char log[2048];
  get_log(object, sizeof log, nullptr, log);
  std::fprintf(stderr, "vsurg render: %s: %s\n", what, log);
}

}  // namespace

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

TableFrame Table(const Eigen::Vector3d& scene_centre, const Eigen::Vector3d& up, double height,
                 double radius) {
  const Eigen::Vector3d e1 = up.unitOrthogonal();
  return {scene_centre - (scene_centre.dot(up) - height) * up, e1, up.cross(e1), radius * 8};
}

}  // namespace vsurg::client::gl
