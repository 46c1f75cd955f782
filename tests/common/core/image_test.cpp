#include "common/core/image.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace vsurg {
namespace {

TEST(ImageTest, PngRoundTripKeepsEveryPixel) {
  const int w = 37, h = 11;
  std::vector<unsigned char> rgb(w * h * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<unsigned char>((i * 7919) % 251);
  const std::string path = testing::TempDir() + "/round_trip.png";
  ASSERT_TRUE(WriteRgbPng(path, w, h, rgb).ok());
  auto image = ReadRgbPng(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  EXPECT_EQ(image->width, w);
  EXPECT_EQ(image->height, h);
  EXPECT_EQ(image->rgb, rgb);
}

TEST(ImageTest, RejectsWhatIsNotAPng) {
  const std::string path = testing::TempDir() + "/not.png";
  std::ofstream(path) << "hello, world";
  EXPECT_FALSE(ReadRgbPng(path).ok());
  EXPECT_FALSE(ReadRgbPng(testing::TempDir() + "/missing.png").ok());
  EXPECT_FALSE(WriteRgbPng(path, 2, 2, std::vector<unsigned char>(5)).ok());
  // A valid file cut short is refused, not read past its end.
  const std::string good = testing::TempDir() + "/good.png";
  ASSERT_TRUE(WriteRgbPng(good, 8, 8, std::vector<unsigned char>(8 * 8 * 3, 200)).ok());
  std::filesystem::resize_file(good, std::filesystem::file_size(good) - 20);
  EXPECT_FALSE(ReadRgbPng(good).ok());
}

}  // namespace
}  // namespace vsurg
