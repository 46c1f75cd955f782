// What a station window's keyboard and mouse are doing: written by the window (GlSurface),
// read by the keyboard-and-mouse device. Plain data, no OpenGL.
#pragma once

#include <cstdint>

namespace vsurg::client {

struct WindowInput {
  // Keys held now: D/A along +x/−x, W/S along +y/−y, Q/E along +z/−z (scene axes).
  bool forward = false, back = false, left = false, right = false, up = false, down = false;
  bool grasp = false;                 // space bar or the left mouse button
  bool mark = false;                  // M or the middle mouse button: a palpation's mark
  bool finish = false;                // Enter pressed: the trainee ends the trial (a search)
  double twist_rad = 0;               // accumulated by dragging with the right mouse button
  double cursor_x = 0, cursor_y = 0;  // px, window coordinates
  // The last command key pressed (an instructor's mode switch: 'O', 'G', 'T', 'H', '[', ']'),
  // and how many have been pressed so far (a reader sees a new press by the count changing).
  char command = 0;
  uint32_t command_presses = 0;
};

}  // namespace vsurg::client
