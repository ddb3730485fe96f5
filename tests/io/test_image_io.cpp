// Image files: EXR (float, half) and PNG round trips, and the errors for missing, corrupt,
// non-finite and absurdly sized images; environment maps read as radiance (negative components
// clamped and counted, NaN, infinity and values above the limit refused).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/io/image_io.hpp"
#include "test_hdr_files.hpp"
#include "test_support.hpp"

namespace {

using softgi::Image;
using softgi::test::ScratchDir;
namespace io = softgi::io;

// Half floats carry an 11-bit significand: round-to-nearest is within 2^-11 relative.
constexpr float kHalfRelative = 1.0f / 2048.0f;
// Largest finite half; write_exr(half) clamps to it.
constexpr float kHalfMax = 65504.0f;
// The sRGB decode of an exactly known byte, in float: a few ulps of pow().
constexpr float kDecodeTolerance = 1e-6f;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

Image random_image(int w, int h, float lo, float hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  Image img(w, h);
  for (auto& p : img.rgb) p = glm::vec3(u(rng), u(rng), u(rng));
  return img;
}

float srgb_decode(float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); }
float srgb_encode(float v) { return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f; }

TEST(io_image, ExrFloatRoundTripIsBitExact) {
  ScratchDir dir;
  Image img = random_image(17, 9, -3.0f, 1e4f, 1);
  img.at(0, 0) = glm::vec3(1e-30f, 3.4e38f, 0.0f);  // extremes of float survive a float EXR
  io::write_exr(dir.file("a.exr"), img);
  const Image back = io::read_image(dir.file("a.exr"));
  ASSERT_EQ(back.width, 17);
  ASSERT_EQ(back.height, 9);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) EXPECT_EQ(back.rgb[i], img.rgb[i]) << "pixel " << i;
  EXPECT_FALSE(std::filesystem::exists(dir.file("a.exr.tmp")));
}

TEST(io_image, ExrHalfRoundTripWithinHalfPrecision) {
  ScratchDir dir;
  Image img = random_image(8, 8, 1e-3f, 1e3f, 2);
  img.at(1, 1) = glm::vec3(1e6f, -1e6f, 65504.0f);  // beyond half range: clamped, not inf
  io::write_exr(dir.file("h.exr"), img, true);
  const Image back = io::read_image(dir.file("h.exr"));
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      if (x == 1 && y == 1) continue;
      for (int k = 0; k < 3; ++k) {
        const float v = img.at(x, y)[k];
        EXPECT_NEAR(back.at(x, y)[k], v, kHalfRelative * std::fabs(v)) << x << "," << y << " channel " << k;
      }
    }
  }
  EXPECT_EQ(back.at(1, 1), glm::vec3(kHalfMax, -kHalfMax, kHalfMax));
  // Half files are smaller than float ones (same content, zip compression): the flag took effect.
  io::write_exr(dir.file("f.exr"), img, false);
  EXPECT_LT(std::filesystem::file_size(dir.file("h.exr")), std::filesystem::file_size(dir.file("f.exr")));
}

TEST(io_image, PngAppliesExposureClampAndSrgb) {
  ScratchDir dir;
  Image img = random_image(13, 7, 0.0f, 2.0f, 3);
  img.at(0, 0) = glm::vec3(-1.0f, 0.0f, 100.0f);
  constexpr float kExposure = 0.7f;
  io::write_png(dir.file("p.png"), img, kExposure);
  const Image back = io::read_image(dir.file("p.png"));  // 8-bit PNG is linearised on read
  ASSERT_EQ(back.width, 13);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const float clamped = std::min(std::max(img.rgb[i][k] * kExposure, 0.0f), 1.0f);
      const float byte = std::round(srgb_encode(clamped) * 255.0f);
      EXPECT_NEAR(back.rgb[i][k], srgb_decode(byte / 255.0f), kDecodeTolerance) << "pixel " << i << " channel " << k;
    }
  }
}

TEST(io_image, PngDisplayIsNotEncoded) {
  ScratchDir dir;
  Image img(4, 1);
  img.at(0, 0) = glm::vec3(0.5f, 0.25f, 1.0f);
  img.at(1, 0) = glm::vec3(2.0f, -1.0f, 0.1f);
  io::write_png_display(dir.file("d.png"), img);
  const Image back = io::read_image(dir.file("d.png"));
  for (int x = 0; x < 2; ++x) {
    for (int k = 0; k < 3; ++k) {
      const float byte = std::round(std::min(std::max(img.at(x, 0)[k], 0.0f), 1.0f) * 255.0f);
      EXPECT_NEAR(back.at(x, 0)[k], srgb_decode(byte / 255.0f), kDecodeTolerance);
    }
  }
}

TEST(io_image, ReadRgbFloatIsRowMajorFromTheTop) {
  ScratchDir dir;
  Image img(3, 2);
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) img.at(x, y) = glm::vec3(float(x), float(y), float(10 * y + x));
  }
  io::write_exr(dir.file("l.exr"), img);
  int w = 0, h = 0;
  std::vector<float> rgb;
  io::read_rgb_float(dir.file("l.exr"), w, h, rgb);
  ASSERT_EQ(w, 3);
  ASSERT_EQ(h, 2);
  ASSERT_EQ(rgb.size(), 18u);
  EXPECT_EQ(rgb[3 * (1 * 3 + 2) + 2], 12.0f);  // pixel (2, 1)
}

TEST(io_image, MissingFileNamesTheFile) {
  ScratchDir dir;
  const std::string e = error_of([&] { io::read_image(dir.file("nope.exr")); });
  EXPECT_NE(e.find("nope.exr: no such file"), std::string::npos) << e;
}

TEST(io_image, CorruptFilesAreErrorsNamingTheFile) {
  ScratchDir dir;
  softgi::test::write_text(dir.file("garbage.exr"), "this is not an image at all, just text");
  std::string e = error_of([&] { io::read_image(dir.file("garbage.exr")); });
  EXPECT_NE(e.find("garbage.exr: "), std::string::npos) << e;
  EXPECT_EQ(e.find("(no exception)"), std::string::npos);

  // A real EXR cut in half.
  io::write_exr(dir.file("full.exr"), random_image(64, 64, 0.0f, 1.0f, 4));
  std::vector<unsigned char> bytes = softgi::test::read_bytes(dir.file("full.exr"));
  bytes.resize(bytes.size() / 2);
  softgi::test::write_bytes(dir.file("cut.exr"), bytes);
  e = error_of([&] { io::read_image(dir.file("cut.exr")); });
  EXPECT_NE(e.find("cut.exr: "), std::string::npos) << e;
  EXPECT_EQ(e.find("(no exception)"), std::string::npos);
}

TEST(io_image, NonFinitePixelIsRefusedAndExistingFileKept) {
  ScratchDir dir;
  const Image good = random_image(4, 4, 0.0f, 1.0f, 5);
  io::write_exr(dir.file("keep.exr"), good);
  Image bad = good;
  bad.at(2, 3).y = std::nanf("");
  const std::string e = error_of([&] { io::write_exr(dir.file("keep.exr"), bad); });
  EXPECT_NE(e.find("keep.exr: pixel (2, 3) channel 1 is nan"), std::string::npos) << e;
  const Image back = io::read_image(dir.file("keep.exr"));
  EXPECT_EQ(back.rgb, good.rgb);
  bad.at(2, 3).y = INFINITY;
  EXPECT_NE(error_of([&] { io::write_png(dir.file("x.png"), bad); }).find("is inf"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.png")));
}

TEST(io_image, AbsurdSizesAndBadArgumentsAreErrors) {
  ScratchDir dir;
  const Image wide(40000, 1);
  std::string e = error_of([&] { io::write_exr(dir.file("wide.exr"), wide); });
  EXPECT_NE(e.find("wide.exr: absurd image size 40000x1"), std::string::npos) << e;
  Image inconsistent(4, 4);
  inconsistent.rgb.resize(3);
  e = error_of([&] { io::write_exr(dir.file("inc.exr"), inconsistent); });
  EXPECT_NE(e.find("inc.exr: image holds 3 pixels"), std::string::npos) << e;
  e = error_of([&] { io::write_png(dir.file("e.png"), Image(2, 2), -1.0f); });
  EXPECT_NE(e.find("e.png: exposure"), std::string::npos) << e;
  e = error_of([&] { io::write_exr(dir.file("no_such_dir/a.exr"), Image(2, 2)); });
  EXPECT_NE(e.find("no_such_dir/a.exr"), std::string::npos) << e;
}

// The scene-file radiance limit (docs/scene_format.md: radiance up to 10^9).
constexpr float kRadianceLimit = 1e9f;

TEST(io_image, EnvironmentMapClampsAndCountsNegativeComponents) {
  ScratchDir dir;
  constexpr int w = 4, h = 3;
  std::vector<float> rgb(w * h * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.125f * float(i);
  rgb[3 * (1 * w + 2) + 0] = -0.57f;  // pixel (2, 1): the lowest
  rgb[3 * (1 * w + 2) + 1] = -0.01f;
  rgb[3 * (2 * w + 3) + 2] = -0.25f;  // pixel (3, 2)
  rgb[3 * (0 * w + 1) + 1] = kRadianceLimit;  // at the limit: allowed
  softgi::test::write_raw_exr(dir.file("neg.exr"), w, h, rgb);
  const io::EnvironmentMap m = io::read_environment_map(dir.file("neg.exr"), kRadianceLimit);
  ASSERT_EQ(m.width, w);
  ASSERT_EQ(m.height, h);
  ASSERT_EQ(m.rgb.size(), rgb.size());
  EXPECT_EQ(m.negative_clamped, 3u);
  EXPECT_EQ(m.lowest, -0.57f);
  EXPECT_EQ(m.lowest_x, 2);
  EXPECT_EQ(m.lowest_y, 1);
  for (std::size_t i = 0; i < rgb.size(); ++i) EXPECT_EQ(m.rgb[i], std::max(rgb[i], 0.0f)) << "component " << i;
  // read_rgb_float is the raw read: the values as stored.
  int rw = 0, rh = 0;
  std::vector<float> raw;
  io::read_rgb_float(dir.file("neg.exr"), rw, rh, raw);
  EXPECT_EQ(raw, rgb);
  // Nothing negative: nothing counted.
  rgb[3 * (1 * w + 2) + 0] = rgb[3 * (1 * w + 2) + 1] = rgb[3 * (2 * w + 3) + 2] = 0.0f;
  softgi::test::write_raw_exr(dir.file("pos.exr"), w, h, rgb);
  const io::EnvironmentMap p = io::read_environment_map(dir.file("pos.exr"), kRadianceLimit);
  EXPECT_EQ(p.negative_clamped, 0u);
  EXPECT_EQ(p.lowest_x, -1);
  EXPECT_EQ(p.rgb, rgb);
}

TEST(io_image, EnvironmentMapRefusesNonFiniteNamingFileAndPixel) {
  ScratchDir dir;
  std::vector<float> rgb(5 * 2 * 3, 1.0f);
  rgb[3 * (1 * 5 + 3) + 1] = std::nanf("");
  softgi::test::write_raw_exr(dir.file("nan.exr"), 5, 2, rgb);
  std::string e = error_of([&] { io::read_environment_map(dir.file("nan.exr"), kRadianceLimit); });
  EXPECT_NE(e.find("nan.exr: pixel (3, 1) channel 1 is nan"), std::string::npos) << e;
  rgb[3 * (1 * 5 + 3) + 1] = -INFINITY;
  softgi::test::write_raw_exr(dir.file("inf.exr"), 5, 2, rgb);
  e = error_of([&] { io::read_environment_map(dir.file("inf.exr"), kRadianceLimit); });
  EXPECT_NE(e.find("inf.exr: pixel (3, 1) channel 1 is -inf"), std::string::npos) << e;
}

TEST(io_image, EnvironmentMapRefusesRadianceAboveTheLimit) {
  ScratchDir dir;
  std::vector<float> rgb(3 * 2 * 3, 0.5f);
  rgb[3 * (0 * 3 + 1) + 2] = 3e38f;
  softgi::test::write_raw_exr(dir.file("huge.exr"), 3, 2, rgb);
  std::string e = error_of([&] { io::read_environment_map(dir.file("huge.exr"), kRadianceLimit); });
  EXPECT_NE(e.find("huge.exr: pixel (1, 0) channel 2 is 3e+38, above the radiance limit 1e+09"), std::string::npos) << e;
  // Radiance HDR (RGBE) too: 2^34 = 1.7e10 is just above the limit and exact in RGBE.
  std::vector<float> hdr = {0.5f, 0.25f, 1.0f, 4.0f, 2.0f, 1.0f, 17179869184.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  softgi::test::write_rgbe_hdr(dir.file("ok.hdr"), 2, 1, hdr);
  const io::EnvironmentMap ok = io::read_environment_map(dir.file("ok.hdr"), kRadianceLimit);
  ASSERT_EQ(ok.width, 2);
  // RGBE keeps 8 bits per channel against the pixel's largest: within 1/256 of it.
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(ok.rgb[k], hdr[k], (k < 3 ? 1.0f : 4.0f) / 256.0f) << "component " << k;
  softgi::test::write_rgbe_hdr(dir.file("huge.hdr"), 2, 2, hdr);
  e = error_of([&] { io::read_environment_map(dir.file("huge.hdr"), kRadianceLimit); });
  EXPECT_NE(e.find("huge.hdr: pixel (0, 1) channel 0 is 1.71799e+10, above the radiance limit 1e+09"), std::string::npos) << e;
}

}  // namespace
