#include "client/render/gl_surface.h"

#define GL_GLEXT_PROTOTYPES 1
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/gl.h>
#include <GL/glext.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <string>

namespace vsurg::client {

struct GlSurface::Impl {
  int width = 0, height = 0;
  bool headless = false;
  // Headless: EGL display and context, and a framebuffer object to draw into.
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  GLuint fbo = 0, colour = 0, depth = 0;
  PFNGLDELETEFRAMEBUFFERSPROC delete_framebuffers = nullptr;
  PFNGLDELETERENDERBUFFERSPROC delete_renderbuffers = nullptr;
  // Window.
  GLFWwindow* window = nullptr;
  mutable std::mutex input_mutex;
  WindowInput input;
  bool rotating = false;
  double last_x = 0;

  ~Impl() {
    if (display != EGL_NO_DISPLAY) {
      if (fbo && delete_framebuffers) delete_framebuffers(1, &fbo);
      if (delete_renderbuffers) {
        if (colour) delete_renderbuffers(1, &colour);
        if (depth) delete_renderbuffers(1, &depth);
      }
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
      eglTerminate(display);
    }
    if (window) {
      glfwDestroyWindow(window);
      glfwTerminate();
    }
  }
};

namespace {

Error GlError(const std::string& what) {
  return Error{ErrorCode::kUnavailable, what, "opengl"};
}

template <typename F>
F Proc(const char* name) {
  return reinterpret_cast<F>(eglGetProcAddress(name));
}

GlSurface::Impl* ImplOf(GLFWwindow* w) {
  return static_cast<GlSurface::Impl*>(glfwGetWindowUserPointer(w));
}

void OnKey(GLFWwindow* w, int key, int, int action, int) {
  if (action == GLFW_REPEAT) return;
  const bool down = action == GLFW_PRESS;
  GlSurface::Impl* impl = ImplOf(w);
  std::lock_guard lock(impl->input_mutex);
  WindowInput& in = impl->input;
  switch (key) {
    case GLFW_KEY_W:
      in.forward = down;
      break;
    case GLFW_KEY_S:
      in.back = down;
      break;
    case GLFW_KEY_A:
      in.left = down;
      break;
    case GLFW_KEY_D:
      in.right = down;
      break;
    case GLFW_KEY_Q:
      in.up = down;
      break;
    case GLFW_KEY_E:
      in.down = down;
      break;
    case GLFW_KEY_SPACE:
      in.grasp = down;
      break;
    case GLFW_KEY_M:
      in.mark = down;
      break;
    case GLFW_KEY_ENTER:
    case GLFW_KEY_KP_ENTER:
      if (down) in.finish = true;
      break;
    case GLFW_KEY_ESCAPE:
      if (down) glfwSetWindowShouldClose(w, GLFW_TRUE);
      break;
    case GLFW_KEY_O:
    case GLFW_KEY_G:
    case GLFW_KEY_T:
    case GLFW_KEY_H:
    case GLFW_KEY_LEFT_BRACKET:
    case GLFW_KEY_RIGHT_BRACKET:
      if (down) {
        // GLFW's key codes for letters and brackets are their ASCII characters.
        in.command = static_cast<char>(key);
        ++in.command_presses;
      }
      break;
    default:
      break;
  }
}

void OnMouseButton(GLFWwindow* w, int button, int action, int) {
  GlSurface::Impl* impl = ImplOf(w);
  std::lock_guard lock(impl->input_mutex);
  if (button == GLFW_MOUSE_BUTTON_LEFT) impl->input.grasp = action == GLFW_PRESS;
  if (button == GLFW_MOUSE_BUTTON_MIDDLE) impl->input.mark = action == GLFW_PRESS;
  if (button == GLFW_MOUSE_BUTTON_RIGHT) {
    impl->rotating = action == GLFW_PRESS;
    impl->last_x = impl->input.cursor_x;
  }
}

void OnCursor(GLFWwindow* w, double x, double y) {
  GlSurface::Impl* impl = ImplOf(w);
  std::lock_guard lock(impl->input_mutex);
  constexpr double kRadPerPixel = 0.005;  // a 160 px drag twists by about 45°
  if (impl->rotating) impl->input.twist_rad += (x - impl->last_x) * kRadPerPixel;
  impl->last_x = x;
  impl->input.cursor_x = x;
  impl->input.cursor_y = y;
}

}  // namespace

GlSurface::GlSurface(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
GlSurface::~GlSurface() = default;

int RequestSoftwareRenderThreads(int threads) {
  const auto in_effect = [] {
    const char* set = std::getenv("LP_NUM_THREADS");
    return set ? std::max(0, std::atoi(set)) : 0;
  };
  if (std::getenv("LP_NUM_THREADS") || threads <= 0) return in_effect();
  ::setenv("LP_NUM_THREADS", std::to_string(threads).c_str(), 1);
  return in_effect();
}

Expected<std::unique_ptr<GlSurface>> GlSurface::CreateHeadless(int width, int height) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192)
    return InvalidArgument("size", "the offscreen image must be 16–8192 pixels a side");
  auto impl = std::make_unique<Impl>();
  impl->width = width;
  impl->height = height;
  impl->headless = true;
  // Mesa's surfaceless platform needs no X server or GPU (llvmpipe renders on the CPU).
  auto get_display = Proc<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
  if (!get_display) return GlError("EGL has no eglGetPlatformDisplayEXT");
  impl->display = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  EGLint major = 0, minor = 0;
  if (impl->display == EGL_NO_DISPLAY || !eglInitialize(impl->display, &major, &minor)) {
    impl->display = EGL_NO_DISPLAY;
    return GlError("cannot open the surfaceless EGL display (is Mesa's libegl-mesa0 installed?)");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) return GlError("EGL cannot bind desktop OpenGL");
  const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (!eglChooseConfig(impl->display, config_attributes, &config, 1, &configs) || configs < 1)
    config = nullptr;  // EGL_KHR_no_config_context: Mesa accepts a context without a config
  // OpenGL 3.3 core (the renderer's GLSL 330); llvmpipe gives 4.5.
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                       3,
                                       EGL_CONTEXT_MINOR_VERSION,
                                       3,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                       EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  impl->context = eglCreateContext(impl->display, config, EGL_NO_CONTEXT, context_attributes);
  if (impl->context == EGL_NO_CONTEXT)
    return GlError(
        "EGL cannot create an OpenGL 3.3 core context (is Mesa's libegl-mesa0 installed?)");
  if (!eglMakeCurrent(impl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, impl->context))
    return GlError("EGL cannot make a surfaceless context current");
  // Framebuffer objects are OpenGL 3.0; take their entry points from the driver.
  auto gen_framebuffers = Proc<PFNGLGENFRAMEBUFFERSPROC>("glGenFramebuffers");
  auto bind_framebuffer = Proc<PFNGLBINDFRAMEBUFFERPROC>("glBindFramebuffer");
  auto gen_renderbuffers = Proc<PFNGLGENRENDERBUFFERSPROC>("glGenRenderbuffers");
  auto bind_renderbuffer = Proc<PFNGLBINDRENDERBUFFERPROC>("glBindRenderbuffer");
  auto storage = Proc<PFNGLRENDERBUFFERSTORAGEPROC>("glRenderbufferStorage");
  auto attach = Proc<PFNGLFRAMEBUFFERRENDERBUFFERPROC>("glFramebufferRenderbuffer");
  auto check = Proc<PFNGLCHECKFRAMEBUFFERSTATUSPROC>("glCheckFramebufferStatus");
  impl->delete_framebuffers = Proc<PFNGLDELETEFRAMEBUFFERSPROC>("glDeleteFramebuffers");
  impl->delete_renderbuffers = Proc<PFNGLDELETERENDERBUFFERSPROC>("glDeleteRenderbuffers");
  if (!gen_framebuffers || !bind_framebuffer || !gen_renderbuffers || !bind_renderbuffer ||
      !storage || !attach || !check)
    return GlError("the OpenGL driver has no framebuffer objects");
  gen_renderbuffers(1, &impl->colour);
  bind_renderbuffer(GL_RENDERBUFFER, impl->colour);
  storage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  gen_renderbuffers(1, &impl->depth);
  bind_renderbuffer(GL_RENDERBUFFER, impl->depth);
  storage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
  gen_framebuffers(1, &impl->fbo);
  bind_framebuffer(GL_FRAMEBUFFER, impl->fbo);
  attach(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, impl->colour);
  attach(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, impl->depth);
  if (check(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    return GlError("the offscreen framebuffer is incomplete");
  return std::unique_ptr<GlSurface>(new GlSurface(std::move(impl)));
}

Expected<std::unique_ptr<GlSurface>> GlSurface::CreateWindow(const std::string& title, int width,
                                                             int height) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192)
    return InvalidArgument("size", "the window must be 16–8192 pixels a side");
  if (!glfwInit()) return GlError("GLFW cannot start (no display? use --headless)");
  auto impl = std::make_unique<Impl>();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_SAMPLES, 0);  // the view copies its cached background in with a blit
  impl->window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (!impl->window) {
    glfwTerminate();
    return GlError("GLFW cannot open a window with an OpenGL 3.3 core context");
  }
  impl->width = width;
  impl->height = height;
  glfwSetWindowUserPointer(impl->window, impl.get());
  glfwSetKeyCallback(impl->window, OnKey);
  glfwSetMouseButtonCallback(impl->window, OnMouseButton);
  glfwSetCursorPosCallback(impl->window, OnCursor);
  glfwMakeContextCurrent(impl->window);
  glfwSwapInterval(1);
  return std::unique_ptr<GlSurface>(new GlSurface(std::move(impl)));
}

int GlSurface::width() const {
  if (impl_->window) glfwGetFramebufferSize(impl_->window, &impl_->width, &impl_->height);
  return impl_->width;
}

int GlSurface::height() const {
  if (impl_->window) glfwGetFramebufferSize(impl_->window, &impl_->width, &impl_->height);
  return impl_->height;
}

bool GlSurface::headless() const {
  return impl_->headless;
}

bool GlSurface::ShouldClose() const {
  return impl_->window && glfwWindowShouldClose(impl_->window);
}

void GlSurface::EndFrame() {
  if (impl_->window) {
    glfwSwapBuffers(impl_->window);
    glfwPollEvents();
  } else {
    glFinish();
  }
}

void GlSurface::Finish() {
  glFinish();
}

RgbImage GlSurface::ReadPixels() const {
  RgbImage image;
  image.width = width();
  image.height = height();
  std::vector<unsigned char> bottom_up(static_cast<size_t>(image.width) * image.height * 3);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  if (impl_->window) glReadBuffer(GL_BACK);
  glReadPixels(0, 0, image.width, image.height, GL_RGB, GL_UNSIGNED_BYTE, bottom_up.data());
  image.rgb.resize(bottom_up.size());
  const size_t stride = static_cast<size_t>(image.width) * 3;
  for (int y = 0; y < image.height; ++y)
    std::memcpy(&image.rgb[y * stride], &bottom_up[(image.height - 1 - y) * stride], stride);
  return image;
}

Status GlSurface::SaveScreenshot(const std::string& path) const {
  const RgbImage image = ReadPixels();
  return WriteRgbPng(path, image.width, image.height, image.rgb);
}

WindowInput GlSurface::Input() const {
  std::lock_guard lock(impl_->input_mutex);
  return impl_->input;
}

}  // namespace vsurg::client
