// What a station window's keyboard and mouse are doing: written by the window (GlSurface),
// read by the keyboard-and-mouse device. Plain data, no OpenGL.
#pragma once

namespace vsurg::client {

struct WindowInput {
  // Keys held now: D/A along +x/−x, W/S along +y/−y, Q/E along +z/−z (scene axes).
  bool forward = false, back = false, left = false, right = false, up = false, down = false;
  bool grasp = false;                 // space bar or the left mouse button
  double twist_rad = 0;               // accumulated by dragging with the right mouse button
  double cursor_x = 0, cursor_y = 0;  // px, window coordinates
};

}  // namespace vsurg::client
