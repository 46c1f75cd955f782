// 8-bit RGB images: PNG in and out through libpng's simplified API (any PNG it reads comes out
// as 8-bit RGB): the stations' and monitors' screenshots.
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

}  // namespace vsurg
