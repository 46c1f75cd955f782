// Where the stations and the monitor draw: a GLFW window, or an offscreen framebuffer in an EGL
// context on Mesa's surfaceless platform (no display needed: tests, CI, docs screenshots).
// Both give an OpenGL 3.3 core context (the renderer's GLSL 330 shaders; Mesa's llvmpipe offers
// 4.5, so CI renders what a GPU does).
//
// Threads: one render thread creates, draws with and destroys a surface (OpenGL contexts are
// current on one thread). Input() may be read from any thread.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "client/device/window_input.h"
#include "common/core/expected.h"
#include "common/core/image.h"

namespace vsurg::client {

// The rasterizer threads a software renderer (Mesa llvmpipe) starts for the surfaces created
// after this call: sets LP_NUM_THREADS, which llvmpipe reads when it starts and other drivers
// ignore, unless the environment already sets it (an operator's choice wins). `threads` 0 leaves
// the driver's default (one per core). Returns the count in effect (0: the driver's default).
// Call before the first surface and before any other thread starts (it changes the process's
// environment, which another thread's getenv may be reading).
int RequestSoftwareRenderThreads(int threads);

class GlSurface {
 public:
  static Expected<std::unique_ptr<GlSurface>> CreateHeadless(int width, int height);
  static Expected<std::unique_ptr<GlSurface>> CreateWindow(const std::string& title, int width,
                                                           int height);
  ~GlSurface();
  GlSurface(const GlSurface&) = delete;
  GlSurface& operator=(const GlSurface&) = delete;

  int width() const;
  int height() const;
  bool headless() const;
  // Window: closed by the user (or Escape). Headless: never.
  bool ShouldClose() const;
  // Waits until the drawing so far is done (for timing a frame).
  void Finish();
  // Presents the frame (window: swap and poll events; headless: finish).
  void EndFrame();
  // The frame just drawn (call before EndFrame for a window), top row first.
  RgbImage ReadPixels() const;
  // ReadPixels written as a PNG file.
  Status SaveScreenshot(const std::string& path) const;
  WindowInput Input() const;

  struct Impl;  // public only for the window's C callbacks in gl_surface.cpp

 private:
  explicit GlSurface(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::client
