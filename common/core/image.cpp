#include "common/core/image.h"

#include <png.h>

#include <cstdio>

namespace vsurg {

Status WriteRgbPng(const std::string& path, int width, int height,
                   const std::vector<unsigned char>& rgb) {
  if (width <= 0 || height <= 0 || rgb.size() != static_cast<size_t>(width) * height * 3)
    return InvalidArgument("image", "size does not match the pixels");
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_RGB;
  const std::string tmp = path + ".tmp";  // renamed into place: a reader never sees half a file
  if (!png_image_write_to_file(&image, tmp.c_str(), 0, rgb.data(), width * 3, nullptr)) {
    const std::string why = image.message;
    png_image_free(&image);
    std::remove(tmp.c_str());
    return Error{ErrorCode::kIoError, "cannot write " + path + ": " + why, "png"};
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return Error{ErrorCode::kIoError, "cannot rename " + tmp, "png"};
  }
  return Status::Ok();
}

Expected<RgbImage> ReadRgbPng(const std::string& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str()))
    return Error{ErrorCode::kParseError, path + ": " + image.message, "png"};
  // Any PNG libpng reads (grey, palette, 16-bit, interlaced, alpha) as 8-bit RGB; alpha is
  // composed onto black, as the old reader dropped it.
  image.format = PNG_FORMAT_RGB;
  RgbImage out;
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  if (image.width == 0 || image.height == 0 || image.width > 1u << 15 || image.height > 1u << 15) {
    png_image_free(&image);
    return Error{ErrorCode::kParseError, path + ": unsupported image size", "png"};
  }
  out.rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr)) {
    const std::string why = image.message;
    png_image_free(&image);
    return Error{ErrorCode::kParseError, path + ": " + why, "png"};
  }
  return out;
}

}  // namespace vsurg
