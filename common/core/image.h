// 8-bit RGB images: PNG in and out through libpng's simplified API (any PNG it reads comes out
// as 8-bit RGB), and the built-in 5×7 bitmap font the stations' HUD draws text with.
#pragma once

#include <string>
#include <vector>

#include "common/core/expected.h"

namespace vsurg {

struct RgbImage {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;  // row-major from the top row, 3 bytes per pixel
};

// Writes an 8-bit RGB image as PNG (through a temporary file renamed into place).
Status WriteRgbPng(const std::string& path, int width, int height,
                   const std::vector<unsigned char>& rgb);
// Reads any PNG (grey, palette, 8- or 16-bit, interlaced, with alpha) as 8-bit RGB.
Expected<RgbImage> ReadRgbPng(const std::string& path);

// The 5×7 font: true where glyph `c` (case-insensitive) has ink at row 0..6, column 0..4.
// Characters without a glyph are blank. Text advances 6 columns per character.
bool GlyphInk(char c, int row, int col);

}  // namespace vsurg
