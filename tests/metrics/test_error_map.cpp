// error_map (viridis of |luminance difference|) and the signed map: colours, scale, range, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "softgi/metrics/image_metrics.hpp"

namespace softgi::metrics {

namespace {

// Map colours are float interpolations of 8-bit stops; the grey inputs' luminance is the grey value up to
// the rounding of the weights' sum (~1e-7 in float), so colours agree to far better than one 8-bit step.
constexpr float kColourTol = 1e-5f;

// Viridis (matplotlib) at t = 0, 0.5, 1: stops 0, 4 and 8 of the 9-stop table.
const glm::vec3 kViridis0 = glm::vec3(0x44, 0x01, 0x54) / 255.0f;
const glm::vec3 kViridisHalf = glm::vec3(0x21, 0x91, 0x8c) / 255.0f;
const glm::vec3 kViridis1 = glm::vec3(0xfd, 0xe7, 0x25) / 255.0f;

void expect_colour(const glm::vec3& got, const glm::vec3& want, const char* what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], kColourTol) << what << " channel " << c;
}

float srgb_to_linear(float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); }
float display_luma(const glm::vec3& c) {
  return 0.2126f * srgb_to_linear(c.r) + 0.7152f * srgb_to_linear(c.g) + 0.0722f * srgb_to_linear(c.b);
}

TEST(ErrorMap, ColoursAtZeroHalfScaleAndBeyond) {
  constexpr double s = 0.4;
  const Image ref(5, 1, glm::vec3(1.0f));
  Image test = ref;
  const float offsets[5] = {0.0f, 0.2f, 0.4f, 0.8f, -0.4f};  // 0, s/2, s, 2s (clamped), -s (absolute value)
  for (int x = 0; x < 5; ++x) test.at(x, 0) += glm::vec3(offsets[x]);
  const Image map = error_map(test, ref, s);
  ASSERT_EQ(map.width, 5);
  ASSERT_EQ(map.height, 1);
  expect_colour(map.at(0, 0), kViridis0, "error 0");
  expect_colour(map.at(1, 0), kViridisHalf, "error scale/2");
  expect_colour(map.at(2, 0), kViridis1, "error = scale");
  expect_colour(map.at(3, 0), kViridis1, "error 2 scale");
  expect_colour(map.at(4, 0), kViridis1, "error -scale");
}

TEST(ErrorMap, RangeAndPerceptualOrder) {
  // A ramp of errors 0..1 across 256 pixels, scale 1: colours stay in [0, 1] and their luminance
  // increases strictly along the ramp (viridis is monotone in lightness).
  const int w = 256;
  const Image ref(w, 1);
  Image test(w, 1);
  for (int x = 0; x < w; ++x) test.at(x, 0) = glm::vec3(static_cast<float>(x) / (w - 1));
  const Image map = error_map(test, ref, 1.0);
  float prev = -1.0f;
  for (int x = 0; x < w; ++x) {
    const glm::vec3 c = map.at(x, 0);
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(c[k], 0.0f);
      EXPECT_LE(c[k], 1.0f);
    }
    const float l = display_luma(c);
    EXPECT_GT(l, prev) << "x = " << x;
    prev = l;
  }
  // Random HDR images with the default scale: every colour in [0, 1].
  std::mt19937 rng(1);
  std::exponential_distribution<float> e(0.5f);
  Image a(31, 29), b(31, 29);
  for (auto& p : a.rgb) p = glm::vec3(e(rng), e(rng), e(rng));
  for (auto& p : b.rgb) p = glm::vec3(e(rng), e(rng), e(rng));
  for (const Image& m : {error_map(a, b), signed_error_map(a, b)})
    for (const auto& c : m.rgb)
      for (int k = 0; k < 3; ++k) {
        ASSERT_GE(c[k], 0.0f);
        ASSERT_LE(c[k], 1.0f);
      }
}

TEST(ErrorMap, DefaultScaleIsThe99thPercentile) {
  // 200 pixels with luminance errors 1..200 (times 1/256, exact in float): the nearest-rank 99th
  // percentile is the 198th smallest error.
  const Image ref(200, 1);
  Image test(200, 1);
  for (int x = 0; x < 200; ++x) test.at(x, 0) = glm::vec3(static_cast<float>(x + 1) / 256.0f);
  EXPECT_NEAR(error_map_scale(test, ref), 198.0 / 256.0, 1e-9);
  EXPECT_EQ(error_map_scale(test, ref, 0.5), 0.5);
  const Image map = error_map(test, ref);
  expect_colour(map.at(197, 0), kViridis1, "99th percentile");
  expect_colour(map.at(199, 0), kViridis1, "above the percentile");
  EXPECT_LT(map.at(196, 0).r, kViridis1.r - 0.005f);  // just below the percentile: not yet the top colour
  // Fewer than 1% of pixels differ: the percentile is 0, the scale falls back to the largest error.
  Image sparse = ref;
  sparse.at(17, 0) = glm::vec3(0.3f);
  EXPECT_NEAR(error_map_scale(sparse, ref), 0.3, 1e-6);
  expect_colour(error_map(sparse, ref).at(17, 0), kViridis1, "single differing pixel");
  // Identical images: every pixel gets the zero colour.
  for (const auto& c : error_map(ref, ref).rgb) expect_colour(c, kViridis0, "identical");
}

TEST(ErrorMap, SignedMapBlueNegativeRedPositive) {
  const Image ref(3, 1, glm::vec3(1.0f));
  Image test = ref;
  test.at(0, 0) -= glm::vec3(0.5f);
  test.at(2, 0) += glm::vec3(0.5f);
  const Image m = signed_error_map(test, ref, 0.5);
  expect_colour(m.at(0, 0), glm::vec3(0x3b, 0x4c, 0xc0) / 255.0f, "negative (test darker)");
  expect_colour(m.at(1, 0), glm::vec3(1.0f), "zero");
  expect_colour(m.at(2, 0), glm::vec3(0xb4, 0x04, 0x26) / 255.0f, "positive (test brighter)");
}

TEST(ErrorMap, BadInputIsAnError) {
  const Image a(4, 4), b(4, 5);
  auto msg = [](auto&& f) -> std::string {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "(no std::invalid_argument thrown)";
  };
  std::string s = msg([&] { error_map(a, b); });
  EXPECT_NE(s.find("4x4"), std::string::npos) << s;
  EXPECT_NE(s.find("4x5"), std::string::npos) << s;
  Image nan = a;
  nan.at(2, 1).r = std::numeric_limits<float>::quiet_NaN();
  s = msg([&] { error_map(a, nan); });
  EXPECT_NE(s.find("(2, 1)"), std::string::npos) << s;
  s = msg([&] { error_map(a, a, -1.0); });
  EXPECT_NE(s.find("scale"), std::string::npos) << s;
  s = msg([&] { signed_error_map(a, a, std::numeric_limits<double>::infinity()); });
  EXPECT_NE(s.find("scale"), std::string::npos) << s;
  s = msg([&] { error_map(Image(), Image()); });
  EXPECT_NE(s.find("empty"), std::string::npos) << s;
}

}  // namespace
}  // namespace softgi::metrics
