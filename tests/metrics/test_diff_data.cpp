// The small images under tests/data/ that tests/cli/diff.cmake feeds to `softgi diff`. They are checked
// in (CMake cannot write EXR) and this test keeps them honest: it rebuilds each from its definition here
// and requires the files to hold exactly that, and it checks the metric values diff.cmake expects.
// Regenerate after changing a definition:
//   SOFTGI_REGENERATE_TEST_DATA=1 ./softgi_tests_metrics --gtest_filter='DiffTestData.*'
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include "softgi/io/image_io.hpp"
#include "softgi/metrics/image_metrics.hpp"

namespace softgi {
namespace {

namespace fs = std::filesystem;

// Float EXR stores every value used below exactly (multiples of 1/4 up to 2.25).
constexpr float kExactTol = 0.0f;
// 8-bit sRGB white/black decode to 1 and 0 up to float rounding in the sRGB curve.
constexpr float kMaskTol = 1e-6f;
// The hand-computed values below are stated to this many digits in diff.cmake's tolerance as well.
constexpr double kValueTol = 1e-9;

constexpr int kSize = 16, kHalf = 8;
constexpr int kNanX = 3, kNanY = 5;

fs::path data_dir() { return fs::path(SOFTGI_SOURCE_DIR) / "tests" / "data"; }

// Reference: grey 0.5 left of column 8, grey 2.0 right of it. Test: reference + 0.25.
Image reference_image() {
  Image img(kSize, kSize);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) img.at(x, y) = glm::vec3(x < kHalf ? 0.5f : 2.0f);
  return img;
}
Image test_image() {
  Image img = reference_image();
  for (auto& p : img.rgb) p += glm::vec3(0.25f);
  return img;
}
Image small_image() { return Image(kHalf, kHalf, glm::vec3(0.5f)); }
// White (counted) left of column 8.
Image mask_image() {
  Image img(kSize, kSize);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kHalf; ++x) img.at(x, y) = glm::vec3(1.0f);
  return img;
}

// The test image with a NaN in G at (3, 5), as a PFM written by hand: the image writer refuses NaN.
// PFM: "PF\n<w> <h>\n<scale>\n", negative scale = little-endian floats, rows stored bottom to top.
void write_nan_pfm(const fs::path& path) {
  Image img = test_image();
  img.at(kNanX, kNanY).g = std::numeric_limits<float>::quiet_NaN();
  std::ofstream out(path, std::ios::binary);
  out << "PF\n" << kSize << " " << kSize << "\n-1.0\n";
  static_assert(std::endian::native == std::endian::little, "PFM writer assumes a little-endian host");
  for (int y = kSize - 1; y >= 0; --y)
    for (int x = 0; x < kSize; ++x) out.write(reinterpret_cast<const char*>(&img.at(x, y)), 3 * sizeof(float));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void expect_same(const Image& got, const Image& want, float tol, const std::string& what) {
  ASSERT_EQ(got.width, want.width) << what;
  ASSERT_EQ(got.height, want.height) << what;
  for (int y = 0; y < want.height; ++y)
    for (int x = 0; x < want.width; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(got.at(x, y)[c], want.at(x, y)[c], tol) << what << " pixel (" << x << ", " << y << ")";
}

TEST(DiffTestData, CheckedInFilesMatchTheirDefinitions) {
  const fs::path dir = data_dir();
  if (std::getenv("SOFTGI_REGENERATE_TEST_DATA")) {
    fs::create_directories(dir);
    io::write_exr((dir / "diff_reference.exr").string(), reference_image());
    io::write_exr((dir / "diff_test.exr").string(), test_image());
    io::write_exr((dir / "diff_small.exr").string(), small_image());
    io::write_png_display((dir / "diff_mask.png").string(), mask_image());
    write_nan_pfm(dir / "diff_nan.pfm");
  }
  for (const char* name : {"diff_reference.exr", "diff_test.exr", "diff_small.exr", "diff_mask.png", "diff_nan.pfm"})
    ASSERT_TRUE(fs::exists(dir / name)) << (dir / name) << " is missing; regenerate with "
                                        << "SOFTGI_REGENERATE_TEST_DATA=1 softgi_tests_metrics --gtest_filter='DiffTestData.*'";
  expect_same(io::read_image((dir / "diff_reference.exr").string()), reference_image(), kExactTol, "diff_reference.exr");
  expect_same(io::read_image((dir / "diff_test.exr").string()), test_image(), kExactTol, "diff_test.exr");
  expect_same(io::read_image((dir / "diff_small.exr").string()), small_image(), kExactTol, "diff_small.exr");
  expect_same(io::read_image((dir / "diff_mask.png").string()), mask_image(), kMaskTol, "diff_mask.png");
  // The NaN file must be rejected naming the pixel (and so be stored top row first, as written).
  try {
    io::read_image((dir / "diff_nan.pfm").string());
    ADD_FAILURE() << "diff_nan.pfm was read without error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("(3, 5)"), std::string::npos) << e.what();
  }
}

// The numbers tests/cli/diff.cmake asserts, computed by hand and checked against compare().
TEST(DiffTestData, ValuesTheCliTestExpects) {
  const metrics::Metrics all = metrics::compare(test_image(), reference_image());
  EXPECT_EQ(all.pixels, 256);
  EXPECT_NEAR(all.rmse, 0.25, kValueTol);
  EXPECT_NEAR(all.max_abs, 0.25, kValueTol);
  EXPECT_NEAR(all.relmse, 0.5 * (0.0625 / 0.26 + 0.0625 / 4.01), kValueTol);  // 0.1279853...
  EXPECT_NEAR(all.psnr, 10 * std::log10(2.0 * 2.0 / 0.0625), kValueTol);      // 18.0618 dB
  EXPECT_GT(all.ssim, 0.0);
  EXPECT_LT(all.ssim, 1.0);
  Mask mask;
  mask.width = mask.height = kSize;
  mask.on.resize(kSize * kSize);
  for (int i = 0; i < kSize * kSize; ++i) mask.on[static_cast<std::size_t>(i)] = (i % kSize) < kHalf;
  const metrics::Metrics left = metrics::compare(test_image(), reference_image(), mask);
  EXPECT_EQ(left.pixels, 128);
  EXPECT_NEAR(left.relmse, 0.0625 / 0.26, kValueTol);                           // 0.2403846...
  EXPECT_NEAR(left.psnr, 10 * std::log10(0.5 * 0.5 / 0.0625), kValueTol);      // 6.0206 dB
  // The counted half is constant (windows never see the other half), so SSIM is the luminance term of
  // x / (1 + x): mu_test = 0.75 / 1.75 = 3/7, mu_ref = 0.5 / 1.5 = 1/3.
  const double mt = 3.0 / 7.0, mr = 1.0 / 3.0, c1 = 1e-4;
  EXPECT_NEAR(left.ssim, (2 * mt * mr + c1) / (mt * mt + mr * mr + c1), kValueTol);  // 0.969238...
}

}  // namespace
}  // namespace softgi
