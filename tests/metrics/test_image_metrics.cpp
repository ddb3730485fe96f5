// compare(): RMSE, relMSE, PSNR, SSIM against closed forms and a brute-force SSIM; masks; bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/metrics/image_metrics.hpp"

namespace softgi::metrics {
namespace {

// Sums of a few hundred doubles: the only error is rounding, far below this.
constexpr double kSumTol = 1e-12;
// Reference SSIM below uses the two-pass variance on a 2D window; the library uses one-pass sums on a
// separable window. Both in double on values in [0, 1): they agree to rounding, ~1e-15 per pixel.
constexpr double kSsimBruteTol = 1e-10;
// SSIM constants restated from Wang et al. 2004 (not read from the library, so a wrong constant there fails).
constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;
constexpr double kSigma = 1.5;
constexpr int kRadius = 5;
// Luminance weights sum to 1 only up to rounding; values below are grey so luma = value * (1 +- 1e-16).
constexpr double kLumaTol = 1e-9;

Image random_image(int w, int h, unsigned seed, float lo = 0.0f, float hi = 4.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  Image img(w, h);
  for (auto& p : img.rgb) p = glm::vec3(u(rng), u(rng), u(rng));
  return img;
}

// Values on a 1/64 grid so that adding 0.25 is exact in float.
Image dyadic_image(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, 4 * 64);
  Image img(w, h);
  for (auto& p : img.rgb) p = glm::vec3(u(rng), u(rng), u(rng)) / 64.0f;
  return img;
}

double tone(double x) { return x / (1.0 + std::abs(x)); }
double ssim_luma(const glm::vec3& p) { return 0.2126 * tone(p.r) + 0.7152 * tone(p.g) + 0.0722 * tone(p.b); }

// Direct evaluation of Wang et al. 2004 Eq. 13-17: per counted pixel, a 2D Gaussian window restricted to
// counted pixels in the image, two-pass weighted mean / variance / covariance, averaged over counted pixels.
double brute_force_ssim(const Image& a, const Image& b, const std::vector<std::uint8_t>& on) {
  const int w = a.width, h = a.height;
  double sum = 0.0;
  long long count = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (!on[static_cast<std::size_t>(y) * w + x]) continue;
      double ws = 0, mx = 0, my = 0;
      auto each = [&](auto&& f) {
        for (int dy = -kRadius; dy <= kRadius; ++dy)
          for (int dx = -kRadius; dx <= kRadius; ++dx) {
            const int u = x + dx, v = y + dy;
            if (u < 0 || v < 0 || u >= w || v >= h || !on[static_cast<std::size_t>(v) * w + u]) continue;
            f(std::exp(-(dx * dx + dy * dy) / (2 * kSigma * kSigma)), ssim_luma(a.at(u, v)), ssim_luma(b.at(u, v)));
          }
      };
      each([&](double g, double p, double q) { ws += g; mx += g * p; my += g * q; });
      mx /= ws;
      my /= ws;
      double sxx = 0, syy = 0, sxy = 0;
      each([&](double g, double p, double q) {
        sxx += g * (p - mx) * (p - mx);
        syy += g * (q - my) * (q - my);
        sxy += g * (p - mx) * (q - my);
      });
      sxx /= ws;
      syy /= ws;
      sxy /= ws;
      sum += (2 * mx * my + kC1) * (2 * sxy + kC2) / ((mx * mx + my * my + kC1) * (sxx + syy + kC2));
      ++count;
    }
  return sum / static_cast<double>(count);
}

Mask left_columns_mask(int w, int h, int columns) {
  Mask m;
  m.width = w;
  m.height = h;
  m.on.assign(static_cast<std::size_t>(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < columns; ++x) m.on[static_cast<std::size_t>(y) * w + x] = 1;
  return m;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument thrown)";
}

TEST(ImageMetrics, IdenticalImagesArePerfect) {
  const Image a = random_image(37, 23, 1);
  const Metrics m = compare(a, a);
  EXPECT_EQ(m.rmse, 0.0);
  EXPECT_EQ(m.relmse, 0.0);
  EXPECT_EQ(m.max_abs, 0.0);
  EXPECT_EQ(m.pixels, 37 * 23);
  // Equal inputs make numerator and denominator of every window's SSIM the same floating-point value.
  EXPECT_EQ(m.ssim, 1.0);
  // MSE = 0: PSNR is +infinity (the CLI prints "inf", JSON "inf").
  EXPECT_TRUE(std::isinf(m.psnr) && m.psnr > 0) << m.psnr;
}

TEST(ImageMetrics, ConstantOffsetClosedForms) {
  constexpr double c = 0.25;
  // Reference: left half 0.5, right half 2.0 (grey); test = reference + c.
  Image ref(16, 10);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 16; ++x) ref.at(x, y) = glm::vec3(x < 8 ? 0.5f : 2.0f);
  Image test = ref;
  for (auto& p : test.rgb) p += glm::vec3(static_cast<float>(c));
  const Metrics m = compare(test, ref);
  EXPECT_NEAR(m.rmse, c, kSumTol);
  EXPECT_NEAR(m.max_abs, c, kSumTol);
  // relMSE by hand: half the pixels c^2 / (0.5^2 + 0.01), half c^2 / (2^2 + 0.01).
  EXPECT_NEAR(m.relmse, 0.5 * (0.0625 / 0.26 + 0.0625 / 4.01), kSumTol);
  // PSNR with peak = reference max 2: 10 log10(4 / 0.0625) = 10 log10(64).
  EXPECT_NEAR(m.psnr, 10.0 * std::log10(64.0), 1e-9);

  // Random dyadic reference, offset of either sign: RMSE = |c| exactly, whatever the content.
  const Image r2 = dyadic_image(31, 17, 2);
  for (double off : {c, -c}) {
    Image t2 = r2;
    for (auto& p : t2.rgb) p += glm::vec3(static_cast<float>(off));
    EXPECT_NEAR(compare(t2, r2).rmse, c, kSumTol) << off;
  }
}

TEST(ImageMetrics, RelMseDividesByReferenceSquaredPlusEpsilon) {
  const Image black(8, 8, glm::vec3(0.0f));
  const Image grey(8, 8, glm::vec3(0.1f));
  const double d2 = static_cast<double>(0.1f) * static_cast<double>(0.1f);
  // Reference black: d^2 / (0 + 0.01). Reference grey: d^2 / (d^2 + 0.01). relMSE is not symmetric.
  EXPECT_NEAR(compare(grey, black).relmse, d2 / 0.01, kSumTol);
  EXPECT_NEAR(compare(black, grey).relmse, d2 / (d2 + 0.01), kSumTol);
  MetricOptions opt;
  opt.relmse_epsilon = 1e-4;
  EXPECT_NEAR(compare(grey, black, {}, opt).relmse, d2 / 1e-4, 1e-9);
}

TEST(ImageMetrics, PsnrPeak) {
  const Image ref = dyadic_image(12, 12, 3);
  Image test = ref;
  for (auto& p : test.rgb) p += glm::vec3(0.125f);
  double ref_max = 0;
  for (const auto& p : ref.rgb) ref_max = std::max({ref_max, double(p.r), double(p.g), double(p.b)});
  const double mse = 0.125 * 0.125;
  EXPECT_NEAR(compare(test, ref).psnr, 10 * std::log10(ref_max * ref_max / mse), 1e-9);
  MetricOptions opt;
  opt.psnr_peak = 1.0;
  EXPECT_NEAR(compare(test, ref, {}, opt).psnr, 10 * std::log10(1.0 / mse), 1e-9);
  // Black reference, no peak given: 10 log10(0 / mse) = -inf rather than NaN.
  const Image black(4, 4);
  const double p = compare(Image(4, 4, glm::vec3(1.0f)), black).psnr;
  EXPECT_TRUE(std::isinf(p) && p < 0) << p;
}

TEST(ImageMetrics, SsimOfConstantImagesMatchesHandComputation) {
  // Constant images: all variances and the covariance vanish, so SSIM reduces to the luminance term
  // (2 mu_a mu_b + C1) / (mu_a^2 + mu_b^2 + C1), with mu = x / (1 + x) of the grey level.
  const Image ref(20, 15, glm::vec3(0.5f));
  const Image test(20, 15, glm::vec3(0.75f));
  const double ma = 0.75 / 1.75, mb = 0.5 / 1.5;
  const double expected = (2 * ma * mb + kC1) / (ma * ma + mb * mb + kC1);
  EXPECT_NEAR(compare(test, ref).ssim, expected, kLumaTol);
  EXPECT_LT(expected, 0.99);  // the test would be weak if the offset barely moved SSIM
}

TEST(ImageMetrics, SsimMatchesBruteForceWindow) {
  // Smooth base plus noise, so windows have structure, variance and covariance.
  Image ref(23, 19), test(23, 19);
  std::mt19937 rng(4);
  std::normal_distribution<float> noise(0.0f, 0.3f);
  for (int y = 0; y < 19; ++y)
    for (int x = 0; x < 23; ++x) {
      const glm::vec3 base(1.0f + std::sin(0.4f * x), 0.5f + 0.02f * y * x, 2.0f * std::cos(0.3f * y) + 2.0f);
      ref.at(x, y) = base;
      test.at(x, y) = glm::max(base + glm::vec3(noise(rng), noise(rng), noise(rng)), glm::vec3(0.0f));
    }
  const std::vector<std::uint8_t> all(23 * 19, 1);
  EXPECT_NEAR(compare(test, ref).ssim, brute_force_ssim(test, ref, all), kSsimBruteTol);

  // Irregular mask: windows exclude uncounted pixels.
  Mask mask;
  mask.width = 23;
  mask.height = 19;
  mask.on.resize(23 * 19);
  for (std::size_t i = 0; i < mask.on.size(); ++i) mask.on[i] = (i * 7919u) % 5u != 0 ? 1 : 0;
  EXPECT_NEAR(compare(test, ref, mask).ssim, brute_force_ssim(test, ref, mask.on), kSsimBruteTol);
}

TEST(ImageMetrics, SsimSymmetricAndBounded) {
  for (unsigned seed = 10; seed < 15; ++seed) {
    const Image a = random_image(19, 21, seed), b = random_image(19, 21, seed + 100);
    const double ab = compare(a, b).ssim, ba = compare(b, a).ssim;
    EXPECT_NEAR(ab, ba, kSumTol);
    EXPECT_GE(ab, -1.0);
    EXPECT_LE(ab, 1.0);
  }
  // Inverted structure: a checkerboard against its complement has negative SSIM.
  Image c(16, 16), d(16, 16);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const bool on = (x + y) % 2 == 0;
      c.at(x, y) = glm::vec3(on ? 1.0f : 0.0f);
      d.at(x, y) = glm::vec3(on ? 0.0f : 1.0f);
    }
  const double s = compare(c, d).ssim;
  EXPECT_LT(s, 0.0);
  EXPECT_GE(s, -1.0);
}

TEST(ImageMetrics, SsimDecreasesMonotonicallyWithNoise) {
  const int w = 48, h = 40;
  Image ref(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      ref.at(x, y) = glm::vec3(0.2f + 0.03f * x, 0.5f + 0.5f * std::sin(0.2f * y), 1.0f + 0.02f * (x + y));
  // One fixed unit-noise field, scaled: each level adds strictly more of the same perturbation.
  std::mt19937 rng(5);
  std::normal_distribution<float> unit(0.0f, 1.0f);
  std::vector<glm::vec3> n(ref.rgb.size());
  for (auto& v : n) v = glm::vec3(unit(rng), unit(rng), unit(rng));
  double prev_ssim = 1.0, prev_rmse = 0.0, rmse_per_sigma = 0.0;
  for (float sigma : {0.01f, 0.03f, 0.1f, 0.3f, 1.0f}) {
    Image test = ref;
    for (std::size_t i = 0; i < n.size(); ++i) test.rgb[i] += sigma * n[i];
    const Metrics m = compare(test, ref);
    EXPECT_LT(m.ssim, prev_ssim) << "sigma " << sigma;
    EXPECT_GT(m.rmse, prev_rmse) << "sigma " << sigma;
    // RMSE is linear in the noise amplitude (float rounding of ref + sigma n: ~1e-7 relative).
    if (rmse_per_sigma == 0.0) rmse_per_sigma = m.rmse / sigma;
    EXPECT_NEAR(m.rmse / sigma, rmse_per_sigma, 1e-4 * rmse_per_sigma) << "sigma " << sigma;
    prev_ssim = m.ssim;
    prev_rmse = m.rmse;
  }
  EXPECT_LT(prev_ssim, 0.9);  // the largest level must matter, or the sweep proves little
}

TEST(ImageMetrics, MaskRestrictsCounting) {
  const Image ref = random_image(24, 16, 6);
  Image test = random_image(24, 16, 7);
  const Mask mask = left_columns_mask(24, 16, 10);
  const Metrics before = compare(test, ref, mask);
  EXPECT_EQ(before.pixels, 10 * 16);
  // Change every uncounted pixel of both images: no metric may move, SSIM included.
  Image test2 = test, ref2 = ref;
  for (int y = 0; y < 16; ++y)
    for (int x = 10; x < 24; ++x) {
      test2.at(x, y) = glm::vec3(100.0f, 0.0f, 7.0f);
      ref2.at(x, y) = glm::vec3(0.0f, 50.0f, 0.0f);
    }
  const Metrics after = compare(test2, ref2, mask);
  EXPECT_EQ(after.rmse, before.rmse);
  EXPECT_EQ(after.relmse, before.relmse);
  EXPECT_EQ(after.psnr, before.psnr);
  EXPECT_EQ(after.ssim, before.ssim);
  EXPECT_EQ(after.max_abs, before.max_abs);
  EXPECT_EQ(after.pixels, before.pixels);
  // A rectangular mask is the same as cropping to the rectangle.
  Image tc(10, 16), rc(10, 16);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 10; ++x) {
      tc.at(x, y) = test.at(x, y);
      rc.at(x, y) = ref.at(x, y);
    }
  const Metrics crop = compare(tc, rc);
  EXPECT_NEAR(crop.rmse, before.rmse, kSumTol);
  EXPECT_NEAR(crop.relmse, before.relmse, kSumTol);
  EXPECT_NEAR(crop.psnr, before.psnr, 1e-9);
  EXPECT_NEAR(crop.ssim, before.ssim, kSumTol);
  EXPECT_EQ(crop.max_abs, before.max_abs);
  // And the mask does change the result relative to all pixels.
  EXPECT_NE(compare(test2, ref2).rmse, before.rmse);
}

TEST(ImageMetrics, NonFinitePixelIsAnErrorNamingIt) {
  Image ref = random_image(9, 7, 8);
  Image test = ref;
  test.at(3, 5).g = std::numeric_limits<float>::quiet_NaN();
  std::string msg = message_of([&] { compare(test, ref); });
  EXPECT_NE(msg.find("(3, 5)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("test"), std::string::npos) << msg;
  EXPECT_NE(msg.find("nan"), std::string::npos) << msg;
  ref.at(8, 0).b = std::numeric_limits<float>::infinity();
  msg = message_of([&] { compare(random_image(9, 7, 9), ref); });
  EXPECT_NE(msg.find("(8, 0)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("reference"), std::string::npos) << msg;
  EXPECT_NE(msg.find("inf"), std::string::npos) << msg;
  // Non-finite pixels are rejected even where the mask does not count them (SSIM windows, error maps).
  msg = message_of([&] { compare(test, random_image(9, 7, 8), left_columns_mask(9, 7, 2)); });
  EXPECT_NE(msg.find("(3, 5)"), std::string::npos) << msg;
}

TEST(ImageMetrics, BadInputIsAnError) {
  const Image a = random_image(8, 6, 11);
  std::string msg = message_of([&] { compare(a, random_image(6, 8, 12)); });
  EXPECT_NE(msg.find("8x6"), std::string::npos) << msg;
  EXPECT_NE(msg.find("6x8"), std::string::npos) << msg;
  msg = message_of([&] { compare(Image(), Image()); });
  EXPECT_NE(msg.find("empty"), std::string::npos) << msg;
  msg = message_of([&] { compare(a, Image()); });
  EXPECT_NE(msg.find("reference image is empty"), std::string::npos) << msg;
  // A mask that selects nothing, or of another size, or whose buffer disagrees with its size.
  msg = message_of([&] { compare(a, a, left_columns_mask(8, 6, 0)); });
  EXPECT_NE(msg.find("selects no pixels"), std::string::npos) << msg;
  msg = message_of([&] { compare(a, a, left_columns_mask(6, 8, 2)); });
  EXPECT_NE(msg.find("6x8"), std::string::npos) << msg;
  Mask short_mask = left_columns_mask(8, 6, 2);
  short_mask.on.pop_back();
  msg = message_of([&] { compare(a, a, short_mask); });
  EXPECT_NE(msg.find("mask buffer"), std::string::npos) << msg;
  Image broken = a;
  broken.rgb.pop_back();
  msg = message_of([&] { compare(broken, a); });
  EXPECT_NE(msg.find("pixel buffer"), std::string::npos) << msg;
  MetricOptions opt;
  opt.relmse_epsilon = 0.0;
  msg = message_of([&] { compare(a, a, {}, opt); });
  EXPECT_NE(msg.find("relmse_epsilon"), std::string::npos) << msg;
  opt = {};
  opt.psnr_peak = std::numeric_limits<double>::quiet_NaN();
  msg = message_of([&] { compare(a, a, {}, opt); });
  EXPECT_NE(msg.find("psnr_peak"), std::string::npos) << msg;
}

}  // namespace
}  // namespace softgi::metrics
