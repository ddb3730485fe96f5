// FLIP and HDR-FLIP (core/src/metrics/flip.cpp): closed forms on flat images against an independent
// restatement of the colour pipeline, the CSF's and the feature detectors' spatial behaviour, symmetry,
// range, the HDR exposure range and tone mappers, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/metrics/flip.hpp"

#include "../support/thrown_message.hpp"

namespace softgi::metrics {
namespace {

// ---------------------------------------------------------------------------------------------------
// The FLIP 2020 colour pipeline restated for flat images (where the CSF filters, normalised to unit sum,
// leave every channel unchanged and the feature detectors, whose lobes cancel, see nothing), with the
// constants as the paper and the authors' reference implementation give them. Not read from the library,
// so a wrong constant there fails.
namespace restated {

constexpr double kM[3][3] = {{10135552.0 / 24577794.0, 8788810.0 / 24577794.0, 4435075.0 / 24577794.0},
                             {2613072.0 / 12288897.0, 8788810.0 / 12288897.0, 887015.0 / 12288897.0},
                             {1425312.0 / 73733382.0, 8788810.0 / 73733382.0, 70074185.0 / 73733382.0}};
constexpr double kQc = 0.7, kPc = 0.4, kPt = 0.95;

double decode(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }
double encode(double c) { return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055; }

std::array<double, 3> hunt_lab(std::array<double, 3> rgb) {
  std::array<double, 3> xyz{}, white{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      xyz[r] += kM[r][c] * rgb[c];
      white[r] += kM[r][c];
    }
  auto f = [](double t) {
    const double d = 6.0 / 29.0;
    return t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
  };
  const double fx = f(xyz[0] / white[0]), fy = f(xyz[1] / white[1]), fz = f(xyz[2] / white[2]);
  const double l = 116 * fy - 16, a = 500 * (fx - fy), b = 200 * (fy - fz);
  return {l, 0.01 * l * a, 0.01 * l * b};
}

double hyab(const std::array<double, 3>& p, const std::array<double, 3>& q) {
  return std::abs(p[0] - q[0]) + std::hypot(p[1] - q[1], p[2] - q[2]);
}

double cmax() { return std::pow(hyab(hunt_lab({0, 1, 0}), hunt_lab({0, 0, 1})), kQc); }

double redistribute(double e) {
  const double c = cmax();
  return e < kPc * c ? kPt / (kPc * c) * e : kPt + (e - kPc * c) / (c - kPc * c) * (1 - kPt);
}

// LDR-FLIP of two flat sRGB colours.
double flat_flip(glm::vec3 test, glm::vec3 ref) {
  std::array<double, 3> t{}, r{};
  for (int c = 0; c < 3; ++c) {
    t[c] = decode(test[c]);
    r[c] = decode(ref[c]);
  }
  return redistribute(std::pow(hyab(hunt_lab(t), hunt_lab(r)), kQc));
}

// Narkowicz's ACES fit with the 0.6 pre-exposure, Hable's curve (A..F, W = 11.2, exposure bias 2) and
// luminance-based Reinhard, as HDR-FLIP 2021 defines them.
double aces(double x) {
  x *= 0.6;
  return std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}
double hable_raw(double x) {
  const double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
  return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}
double hable(double x) { return std::clamp(hable_raw(2.0 * x) / hable_raw(11.2), 0.0, 1.0); }
// The Y row of the exact-rational RGB -> XYZ matrix above, as the authors compute luminance.
double luminance(const glm::dvec3& c) { return kM[1][0] * c.r + kM[1][1] * c.g + kM[1][2] * c.b; }

// The exposed value each curve maps to 0.85, by bisection on the restated curves (independent of the
// library's closed-form root).
double value_mapped_to(double target, double (*curve)(double)) {
  double lo = 0.0, hi = 1e3;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (curve(mid) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}
double reinhard_scalar(double x) { return x / (1.0 + x); }

}  // namespace restated

// ---------------------------------------------------------------------------------------------------
// Tolerances.

// The library filters in float: a flat channel passes a unit-sum float kernel, giving relative rounding of
// ~1e-7 on values up to ~500 (Cx, Cz) and ~100 (L*), i.e. HyAB errors ~1e-4 at worst; the HyAB -> FLIP
// map has slope <= 0.06 per unit above distance 1. 1e-5 covers it with margin and is far below any
// constant's effect (a 1 % change of any constant moves these values by > 1e-3).
constexpr double kFlatTol = 1e-5;
// Float rounding of pow(ec, 1 - ef) recomputed from the stored float terms.
constexpr double kTermsTol = 1e-6;
// Sums of a few thousand floats in double.
constexpr double kMeanTol = 1e-12;
// HDR vs LDR of the restated tone-mapped, sRGB-encoded images: the encode / float / decode round trip
// perturbs linear values by ~1e-7 relative; near zero distance the pow(., 0.7) and the feature term's
// sqrt amplify that to ~1e-4 per pixel at most. 1e-3 per pixel and 1e-5 on the mean leave margin while a
// wrong tone-mapping constant changes the map by > 1e-2.
constexpr double kHdrLdrPixelTol = 1e-3;
constexpr double kHdrLdrMeanTol = 1e-5;
// Exposures are logarithms of ratios of doubles.
constexpr double kExposureTol = 1e-9;

Image flat(int w, int h, glm::vec3 c) { return Image(w, h, c); }

Image random_ldr(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image img(w, h);
  for (auto& p : img.rgb) p = glm::vec3(u(rng), u(rng), u(rng));
  return img;
}

// Smooth structure plus noise, so that both the colour and the feature pipelines have work to do.
Image structured_ldr(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float fx = 0.05f + 0.3f * u(rng), fy = 0.05f + 0.3f * u(rng), ph = 6.0f * u(rng);
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float s = 0.5f + 0.35f * std::sin(fx * x + ph) * std::cos(fy * y);
      const float n = 0.15f * (u(rng) - 0.5f);
      img.at(x, y) = glm::clamp(glm::vec3(s + n, 0.8f * s + 0.1f, 1.0f - s + n), 0.0f, 1.0f);
    }
  return img;
}

Image random_hdr(int w, int h, unsigned seed, float hi = 8.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float base = 0.05f + hi * std::pow(u(rng), 3.0f);
      img.at(x, y) = glm::vec3(base * (0.5f + u(rng)), base * (0.5f + u(rng)), base * (0.5f + u(rng)));
    }
  return img;
}

double mean_of(const std::vector<float>& v) {
  double s = 0.0;
  for (float e : v) s += e;
  return s / static_cast<double>(v.size());
}

// sRGB encode for checkerboards "of the same mean": the CSFs average linear light.
float srgb_encode(double linear) { return static_cast<float>(restated::encode(linear)); }

Image checkerboard(int w, int h, int square, float a, float b) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.at(x, y) = glm::vec3(((x / square + y / square) % 2) ? b : a);
  return img;
}

using test::thrown_message;

// ---------------------------------------------------------------------------------------------------
// LDR-FLIP.

TEST(FlipLdr, DefaultObserverIs67PixelsPerDegree) {
  // 0.7 m from a 0.7 m wide 3840-pixel display (FLIP 2020's default): 3840 pi / 180 = 67.02.
  EXPECT_DOUBLE_EQ(kFlipDefaultPpd, 3840.0 * std::numbers::pi / 180.0);
  EXPECT_DOUBLE_EQ(FlipOptions{}.ppd, kFlipDefaultPpd);
  EXPECT_DOUBLE_EQ(flip_pixels_per_degree(0.7, 0.7, 3840), kFlipDefaultPpd);
  EXPECT_NEAR(kFlipDefaultPpd, 67.0206, 1e-4);
}

TEST(FlipLdr, IdenticalImagesGiveExactlyZero) {
  for (unsigned seed : {1u, 2u}) {
    const Image a = structured_ldr(40, 30, seed);
    const FlipResult r = flip_ldr(a, a);
    ASSERT_EQ(r.width, 40);
    ASSERT_EQ(r.height, 30);
    ASSERT_EQ(r.error.size(), 40u * 30u);
    for (float e : r.error) ASSERT_EQ(e, 0.0f);
    EXPECT_EQ(r.mean, 0.0);
  }
}

TEST(FlipLdr, EveryPixelInUnitIntervalAndMeanIsTheAverage) {
  // Noise against noise, and per-pixel random cube corners (the most extreme colour pairs).
  std::mt19937 rng(7);
  Image ca(48, 48), cb(48, 48);
  for (std::size_t i = 0; i < ca.rgb.size(); ++i) {
    ca.rgb[i] = glm::vec3(float(rng() & 1), float(rng() & 1), float(rng() & 1));
    cb.rgb[i] = glm::vec3(float(rng() & 1), float(rng() & 1), float(rng() & 1));
  }
  const std::vector<std::pair<Image, Image>> pairs = {
      {random_ldr(48, 48, 3), random_ldr(48, 48, 4)}, {structured_ldr(48, 48, 5), structured_ldr(48, 48, 6)}, {ca, cb}};
  for (const auto& [a, b] : pairs) {
    const FlipResult r = flip_ldr(a, b);
    for (float e : r.error) {
      ASSERT_GE(e, 0.0f);
      ASSERT_LE(e, 1.0f);
    }
    EXPECT_NEAR(r.mean, mean_of(r.error), kMeanTol);
    EXPECT_GT(r.mean, 0.0);
  }
}

TEST(FlipLdr, SymmetricInItsArgumentsBitForBit) {
  // Both images go through the same filters; the colour term combines them through |dL| and the
  // Euclidean chroma distance, the feature term through |.| of norm differences: swapping is exact.
  for (unsigned seed : {11u, 12u, 13u}) {
    const Image a = structured_ldr(37, 29, seed), b = random_ldr(37, 29, seed + 100);
    FlipOptions opt;
    opt.keep_terms = true;
    const FlipResult ab = flip_ldr(a, b, opt), ba = flip_ldr(b, a, opt);
    ASSERT_EQ(ab.error.size(), ba.error.size());
    for (std::size_t i = 0; i < ab.error.size(); ++i) {
      ASSERT_EQ(ab.error[i], ba.error[i]) << "pixel " << i;
      ASSERT_EQ(ab.feature_term[i], ba.feature_term[i]) << "pixel " << i;
    }
    EXPECT_EQ(ab.mean, ba.mean);
  }
}

TEST(FlipLdr, FlatPatchesMatchTheRestatedColourPipeline) {
  // Flat images: no features, so FLIP = the redistributed colour difference, a closed form.
  const std::vector<std::pair<glm::vec3, glm::vec3>> cases = {
      {{0, 0, 0}, {1, 1, 1}},           {{0.5f, 0.5f, 0.5f}, {0.6f, 0.6f, 0.6f}}, {{0.2f, 0.4f, 0.8f}, {0.3f, 0.4f, 0.7f}},
      {{0.9f, 0.1f, 0.1f}, {0.1f, 0.9f, 0.1f}}, {{0.02f, 0.02f, 0.02f}, {0.2f, 0.2f, 0.2f}}, {{1, 1, 0}, {0, 0, 1}}};
  for (const auto& [t, r] : cases) {
    FlipOptions opt;
    opt.keep_terms = true;
    const FlipResult res = flip_ldr(flat(12, 10, t), flat(12, 10, r), opt);
    const double expected = restated::flat_flip(t, r);
    for (std::size_t i = 0; i < res.error.size(); ++i) {
      ASSERT_NEAR(res.error[i], expected, kFlatTol) << "test " << t.r << "," << t.g << "," << t.b;
      ASSERT_EQ(res.feature_term[i], 0.0f);  // flat: the detector lobes cancel exactly
    }
  }
}

TEST(FlipLdr, BlackVersusWhiteAndGreenVersusBlue) {
  // Black vs white: HyAB = 100 (L* 0 vs 100, no chroma), 100^0.7 = 25.12 lies above pc cmax, so the value
  // is in the top band (pt, 1): 0.95 + (25.12 - 0.4 cmax) / (0.6 cmax) * 0.05 with cmax = 41.28 -> 0.9674.
  const double cmax = restated::cmax();
  const double bw = 0.95 + (std::pow(100.0, 0.7) - 0.4 * cmax) / (0.6 * cmax) * 0.05;
  EXPECT_NEAR(cmax, 41.276, 1e-3);  // (HyAB(green, blue) = 203.30)^0.7
  EXPECT_NEAR(bw, 0.96738, 1e-5);
  const FlipResult r = flip_ldr(flat(16, 16, glm::vec3(0)), flat(16, 16, glm::vec3(1)));
  for (float e : r.error) ASSERT_NEAR(e, bw, kFlatTol);
  // Green vs blue is cmax by definition: FLIP's largest value, 1.
  const FlipResult gb = flip_ldr(flat(16, 16, {0, 1, 0}), flat(16, 16, {0, 0, 1}));
  for (float e : gb.error) ASSERT_NEAR(e, 1.0, kFlatTol);
}

TEST(FlipLdr, CmaxBoundsEveryColourPairOfTheRgbCube) {
  // The redistribution assumes HyAB(Hunt(green), Hunt(blue)) is the largest distance in the cube (FLIP
  // 2020). Check the restated pipeline on a 9^3 grid, every pair, and the library on the 8 corners.
  std::vector<std::array<double, 3>> lab;
  constexpr int kSteps = 9;
  for (int r = 0; r < kSteps; ++r)
    for (int g = 0; g < kSteps; ++g)
      for (int b = 0; b < kSteps; ++b)
        lab.push_back(restated::hunt_lab({r / (kSteps - 1.0), g / (kSteps - 1.0), b / (kSteps - 1.0)}));
  const double gb = restated::hyab(restated::hunt_lab({0, 1, 0}), restated::hunt_lab({0, 0, 1}));
  double largest = 0.0;
  for (std::size_t i = 0; i < lab.size(); ++i)
    for (std::size_t j = i + 1; j < lab.size(); ++j) largest = std::max(largest, restated::hyab(lab[i], lab[j]));
  EXPECT_LE(largest, gb * (1 + 1e-12));
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) {
      const glm::vec3 a(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1));
      const glm::vec3 b(float(j & 1), float((j >> 1) & 1), float((j >> 2) & 1));
      const FlipResult res = flip_ldr(flat(4, 4, a), flat(4, 4, b));
      EXPECT_NEAR(res.error[0], restated::flat_flip(a, b), kFlatTol) << i << " vs " << j;
      EXPECT_LE(res.error[0], 1.0f);
    }
}

TEST(FlipLdr, FlatColourDifferenceIsMonotoneInTheColourDistance) {
  // Grey steps and a red-only step away from mid grey: each larger step is strictly worse.
  for (int axis = 0; axis < 2; ++axis) {
    double previous = 0.0;
    for (int k = 1; k <= 10; ++k) {
      const float d = 0.045f * k;
      const glm::vec3 ref(0.5f), test = axis == 0 ? glm::vec3(0.5f + d) : glm::vec3(0.5f + d, 0.5f, 0.5f);
      const double e = flip_ldr(flat(8, 8, test), flat(8, 8, ref)).mean;
      EXPECT_GT(e, previous) << "axis " << axis << " step " << k;
      previous = e;
    }
  }
}

TEST(FlipLdr, ContrastSensitivityBlursAwayHighFrequencies) {
  // A black / white checkerboard against the flat grey of the same linear mean. With 1-pixel squares
  // (33 cycles / degree at 67 PPD) the CSFs average the pattern to that grey and the feature detectors
  // (sigma 2.7 pixels) do not resolve it: FLIP is small. With 16-pixel squares (2 cycles / degree, near
  // the achromatic CSF's peak) every square is seen as black or white against grey.
  const float grey = srgb_encode(0.5);
  const Image g = flat(64, 64, glm::vec3(grey));
  const double fine = flip_ldr(checkerboard(64, 64, 1, 0.0f, 1.0f), g).mean;
  const double coarse = flip_ldr(checkerboard(64, 64, 16, 0.0f, 1.0f), g).mean;
  // Unfiltered, black or white vs grey would be 0.78 per pixel (restated closed form) at either size.
  EXPECT_GT(restated::flat_flip(glm::vec3(0), glm::vec3(grey)), 0.5);
  EXPECT_GT(coarse, 0.5);
  EXPECT_LT(fine, 0.1);
  EXPECT_LT(fine, 0.1 * coarse);
}

TEST(FlipLdr, FewerPixelsPerDegreeMakeFinePatternsVisible) {
  // The same 2-pixel checkerboard seen from farther away (67 PPD) is blurred more than close up (10 PPD,
  // where each pixel covers 0.1 degrees).
  const float grey = srgb_encode(0.5);
  const Image c = checkerboard(48, 48, 2, 0.0f, 1.0f), g = flat(48, 48, glm::vec3(grey));
  FlipOptions near_opt, far_opt;
  near_opt.ppd = 10.0;
  far_opt.ppd = 67.0;
  const double near_err = flip_ldr(c, g, near_opt).mean, far_err = flip_ldr(c, g, far_opt).mean;
  EXPECT_GT(near_err, 2.0 * far_err);
}

TEST(FlipLdr, ShiftedEdgeGivesAFeatureResponseConcentratedAtTheEdge) {
  // A vertical edge between sRGB 0.3 and 0.7 at column 32 in the reference, at column 33 in the test:
  // only column 32 differs.
  constexpr int kW = 64, kH = 6, kEdge = 32;
  Image ref(kW, kH), test(kW, kH);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      ref.at(x, y) = glm::vec3(x < kEdge ? 0.3f : 0.7f);
      test.at(x, y) = glm::vec3(x < kEdge + 1 ? 0.3f : 0.7f);
    }
  FlipOptions opt;
  opt.keep_terms = true;
  const FlipResult r = flip_ldr(test, ref, opt);
  // Reach of the filters at the default PPD: feature detectors ceil(3 * 0.041 * PPD) = 9 pixels, CSF
  // ceil(3 sqrt(0.04 / (2 pi^2)) PPD) = 10 pixels. Beyond them both images look the same: exactly 0.
  const int feature_reach = static_cast<int>(std::ceil(3.0 * 0.5 * 0.082 * opt.ppd));
  const int csf_reach = static_cast<int>(std::ceil(3.0 * std::sqrt(0.04 / (2 * std::numbers::pi * std::numbers::pi)) * opt.ppd));
  ASSERT_EQ(feature_reach, 9);
  ASSERT_EQ(csf_reach, 10);
  // Both images have an edge of the same strength, one pixel apart, so at the edge their edge responses
  // (a Gaussian profile of sd = 0.041 PPD = 2.75 pixels, peak = the luminance step 0.375 for unit lobes)
  // nearly cancel; their difference peaks about one sd away at 0.375 e^(-1/2) / 2.75 = 0.083 per pixel of
  // shift, giving deltaE_f = (0.083 / sqrt 2)^(1/2) = 0.24. The peak lies within 2 sd (5 pixels) of the
  // edge and is above 0.2 (the point detector only adds to it); an implementation without the feature
  // term, or with the detectors mis-normalised by a factor of 2, misses these.
  constexpr int kNear = 5;
  constexpr float kPeakFloor = 0.2f;
  double near_sum = 0.0, total_sum = 0.0;
  for (int y = 0; y < kH; ++y) {
    int argmax = 0;
    for (int x = 0; x < kW; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * kW + x;
      const float ef = r.feature_term[i], ec = r.color_term[i], e = r.error[i];
      if (std::abs(x - kEdge) > feature_reach) {
        ASSERT_EQ(ef, 0.0f) << x;
      }
      if (std::abs(x - kEdge) > csf_reach) {
        ASSERT_EQ(ec, 0.0f) << x;
        ASSERT_EQ(e, 0.0f) << x;
      }
      // deltaE = deltaE_c ^ (1 - deltaE_f) >= deltaE_c: features only ever raise the error.
      ASSERT_NEAR(e, std::pow(double(ec), 1.0 - double(ef)), kTermsTol) << x;
      ASSERT_GE(e + kTermsTol, ec) << x;
      if (ef > r.feature_term[static_cast<std::size_t>(y) * kW + argmax]) argmax = x;
      total_sum += ef;
      if (std::abs(x - kEdge) <= kNear) near_sum += ef;
    }
    EXPECT_LE(std::abs(argmax - kEdge), kNear) << "row " << y;
    EXPECT_GT(r.feature_term[static_cast<std::size_t>(y) * kW + argmax], kPeakFloor);
    // The feature term lifts the error at the edge well above the colour term alone.
    const std::size_t at = static_cast<std::size_t>(y) * kW + argmax;
    EXPECT_GT(r.error[at], r.color_term[at] + 0.05f);
  }
  EXPECT_GT(near_sum, 0.5 * total_sum);  // the columns within 2 sigma carry most of the response
}

TEST(FlipLdr, TermsOnlyWhenAsked) {
  const Image a = structured_ldr(16, 16, 1), b = structured_ldr(16, 16, 2);
  const FlipResult plain = flip_ldr(a, b);
  EXPECT_TRUE(plain.color_term.empty());
  EXPECT_TRUE(plain.feature_term.empty());
  FlipOptions opt;
  opt.keep_terms = true;
  const FlipResult kept = flip_ldr(a, b, opt);
  EXPECT_EQ(kept.color_term.size(), a.rgb.size());
  EXPECT_EQ(kept.error, plain.error);
}

// ---------------------------------------------------------------------------------------------------
// HDR-FLIP.

TEST(FlipHdr, IdenticalImagesGiveZero) {
  const Image a = random_hdr(32, 24, 1);
  const FlipResult r = flip_hdr(a, a);
  for (float e : r.error) ASSERT_EQ(e, 0.0f);
  EXPECT_EQ(r.mean, 0.0);
  EXPECT_GE(r.exposures.size(), 2u);
}

TEST(FlipHdr, DoublingTheRadianceIsAnErrorAtEveryLitPixel) {
  // At the start exposure the reference's brightest pixel maps to 0.85 and twice it stays below the
  // ACES curve's clamp, so no pixel's difference is tone-mapped away at every exposure.
  const Image ref = random_hdr(32, 24, 2);
  Image test = ref;
  for (auto& p : test.rgb) p *= 2.0f;
  const FlipResult r = flip_hdr(test, ref);
  for (float e : r.error) ASSERT_GT(e, 0.0f);
  EXPECT_GT(r.mean, 0.1);
}

TEST(FlipHdr, ExposureRangeFromTheReference) {
  // 16 grey pixels: 8 of luminance 0.25, 7 of 0.5, one of 4: max 4, median (0.25 + 0.5) / 2 = 0.375
  // (the mean of the two middle values, numpy's 50th percentile as the authors use it).
  Image ref(4, 4, glm::vec3(0.25f));
  for (int i = 8; i < 15; ++i) ref.rgb[static_cast<std::size_t>(i)] = glm::vec3(0.5f);
  ref.rgb[15] = glm::vec3(4.0f);
  const Image test = random_hdr(4, 4, 9, 2.0f);
  struct Case {
    FlipToneMapper tm;
    double x;  // exposed value the tone mapper maps to 0.85
  };
  const Case cases[] = {{FlipToneMapper::aces, restated::value_mapped_to(0.85, restated::aces)},
                        {FlipToneMapper::hable, restated::value_mapped_to(0.85, restated::hable)},
                        {FlipToneMapper::reinhard, restated::value_mapped_to(0.85, restated::reinhard_scalar)}};
  for (const Case& c : cases) {
    FlipOptions opt;
    opt.tone_mapper = c.tm;
    const FlipResult r = flip_hdr(test, ref, opt);
    const double start = std::log2(c.x / 4.0), stop = std::log2(c.x / 0.375);
    EXPECT_NEAR(r.start_exposure, start, kExposureTol);
    EXPECT_NEAR(r.stop_exposure, stop, kExposureTol);
    // max(2, ceil(stop - start)) = ceil(log2(4 / 0.375)) = ceil(3.415) = 4 exposures, evenly spaced.
    ASSERT_EQ(r.exposures.size(), 4u);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(r.exposures[static_cast<std::size_t>(i)], start + i * (stop - start) / 3.0, kExposureTol);
  }
  // Narkowicz ACES with pre-exposure 0.6 maps x = 2.1189 to 0.85 (positive root of the quadratic).
  EXPECT_NEAR(cases[0].x, 2.1189, 1e-4);
  EXPECT_NEAR(cases[2].x, 0.85 / 0.15, 1e-9);
}

TEST(FlipHdr, SingleExposureEqualsLdrFlipOfTheToneMappedImages) {
  const Image ref = random_hdr(40, 32, 3, 3.0f);
  Image test = random_hdr(40, 32, 4, 3.0f);
  for (std::size_t i = 0; i < test.rgb.size(); ++i) test.rgb[i] = 0.6f * test.rgb[i] + 0.7f * ref.rgb[i];
  struct Case {
    FlipToneMapper tm;
    double exposure;
  };
  for (const Case c : {Case{FlipToneMapper::aces, -0.5}, Case{FlipToneMapper::hable, 0.75}, Case{FlipToneMapper::reinhard, 0.25}}) {
    auto tone = [&](const Image& img) {
      Image out(img.width, img.height);
      const double s = std::exp2(c.exposure);
      for (std::size_t i = 0; i < img.rgb.size(); ++i) {
        const glm::dvec3 x = glm::dvec3(img.rgb[i]) * s;
        glm::dvec3 y;
        if (c.tm == FlipToneMapper::reinhard) y = glm::clamp(x / (1.0 + restated::luminance(x)), 0.0, 1.0);
        for (int k = 0; k < 3; ++k) {
          if (c.tm == FlipToneMapper::aces) y[k] = restated::aces(x[k]);
          if (c.tm == FlipToneMapper::hable) y[k] = restated::hable(x[k]);
          out.rgb[i][k] = static_cast<float>(restated::encode(y[k]));
        }
      }
      return out;
    };
    FlipOptions opt;
    opt.tone_mapper = c.tm;
    opt.start_exposure = opt.stop_exposure = c.exposure;
    opt.num_exposures = 1;
    const FlipResult hdr = flip_hdr(test, ref, opt);
    const FlipResult ldr = flip_ldr(tone(test), tone(ref));
    ASSERT_EQ(hdr.exposures.size(), 1u);
    EXPECT_DOUBLE_EQ(hdr.exposures[0], c.exposure);
    double worst = 0.0;
    for (std::size_t i = 0; i < hdr.error.size(); ++i) worst = std::max(worst, double(std::abs(hdr.error[i] - ldr.error[i])));
    EXPECT_LT(worst, kHdrLdrPixelTol);
    EXPECT_NEAR(hdr.mean, ldr.mean, kHdrLdrMeanTol);
    EXPECT_GT(hdr.mean, 0.05);  // a real difference, so the comparison means something
  }
}

TEST(FlipHdr, ErrorIsThePerPixelMaximumOverExposures) {
  const Image ref = random_hdr(24, 20, 5), test = random_hdr(24, 20, 6);
  FlipOptions all;
  all.start_exposure = -3.0;
  all.stop_exposure = 1.0;
  all.num_exposures = 3;
  const FlipResult r = flip_hdr(test, ref, all);
  ASSERT_EQ(r.exposures, (std::vector<double>{-3.0, -1.0, 1.0}));
  std::vector<std::vector<float>> single;
  for (double e : r.exposures) {
    FlipOptions one;
    one.start_exposure = one.stop_exposure = e;
    one.num_exposures = 1;
    single.push_back(flip_hdr(test, ref, one).error);
  }
  std::array<int, 3> wins{};
  for (std::size_t i = 0; i < r.error.size(); ++i) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < 3; ++k)
      if (single[k][i] > single[best][i]) best = k;
    ++wins[best];
    ASSERT_EQ(r.error[i], single[best][i]) << "pixel " << i;
  }
  // Different pixels take their maximum at different exposures, so the result is not one exposure's map.
  EXPECT_GE(std::count_if(wins.begin(), wins.end(), [](int n) { return n > 0; }), 2);
}

TEST(FlipHdr, NegativeValuesCountAsZero) {
  const Image ref = random_hdr(16, 16, 7);
  Image neg = random_hdr(16, 16, 8), clamped = neg;
  for (std::size_t i = 0; i < neg.rgb.size(); i += 3) {
    neg.rgb[i].g = -1.5f;
    clamped.rgb[i].g = 0.0f;
  }
  EXPECT_EQ(flip_hdr(neg, ref).error, flip_hdr(clamped, ref).error);
}

TEST(FlipHdr, BlackReferenceUsesExposureZero) {
  const FlipResult r = flip_hdr(random_hdr(8, 8, 1), flat(8, 8, glm::vec3(0)));
  EXPECT_EQ(r.start_exposure, 0.0);
  EXPECT_EQ(r.stop_exposure, 0.0);
  EXPECT_EQ(r.exposures, (std::vector<double>{0.0, 0.0}));
  EXPECT_GT(r.mean, 0.0);
}

TEST(FlipHdr, MostlyBlackReferenceNeedsAStopExposure) {
  Image ref(4, 4, glm::vec3(0));
  ref.rgb[0] = glm::vec3(1.0f);
  const Image test = random_hdr(4, 4, 2);
  EXPECT_NE(thrown_message([&] { flip_hdr(test, ref); }).find("median luminance is 0"), std::string::npos);
  FlipOptions opt;
  opt.stop_exposure = 2.0;
  const FlipResult r = flip_hdr(test, ref, opt);
  EXPECT_EQ(r.stop_exposure, 2.0);
  EXPECT_NEAR(r.start_exposure, std::log2(restated::value_mapped_to(0.85, restated::aces)), kExposureTol);
}

TEST(FlipHdr, PositiveMedianFallbackTakesTheMedianOfTheLitPixels) {
  // 10 of 16 pixels black; the lit ones are 0.25 (3), 0.5 (2) and 4 (1): their median (the mean of the
  // middle two, as for the whole image) is 0.375, so the stop exposure is log2(x / 0.375). Without the
  // fallback the same reference is an error (tested above).
  Image ref(4, 4, glm::vec3(0));
  for (int i = 0; i < 3; ++i) ref.rgb[static_cast<std::size_t>(i)] = glm::vec3(0.25f);
  for (int i = 3; i < 5; ++i) ref.rgb[static_cast<std::size_t>(i)] = glm::vec3(0.5f);
  ref.rgb[5] = glm::vec3(4.0f);
  FlipOptions opt;
  opt.positive_median_fallback = true;
  const FlipResult r = flip_hdr(random_hdr(4, 4, 3), ref, opt);
  const double x = restated::value_mapped_to(0.85, restated::aces);
  EXPECT_TRUE(r.stop_from_positive_median);
  EXPECT_NEAR(r.stop_exposure, std::log2(x / 0.375), kExposureTol);
  EXPECT_NEAR(r.start_exposure, std::log2(x / 4.0), kExposureTol);
  // A reference with a positive median keeps the papers' rule and does not report the fallback.
  const FlipResult lit = flip_hdr(random_hdr(4, 4, 3), random_hdr(4, 4, 4), opt);
  EXPECT_FALSE(lit.stop_from_positive_median);
  EXPECT_EQ(lit.stop_exposure, flip_hdr(random_hdr(4, 4, 3), random_hdr(4, 4, 4)).stop_exposure);
}

TEST(FlipMean, MaskedMeanAveragesTheSelectedPixelsOnly) {
  const FlipResult r = flip_ldr(structured_ldr(20, 10, 5), structured_ldr(20, 10, 6));
  Mask left{20, 10, std::vector<std::uint8_t>(200, 0)};
  double sum = 0.0;
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 7; ++x) {
      left.on[static_cast<std::size_t>(y * 20 + x)] = 1;
      sum += r.error[static_cast<std::size_t>(y * 20 + x)];
    }
  EXPECT_NEAR(flip_mean(r, left), sum / 70.0, kMeanTol);
  EXPECT_NE(flip_mean(r, left), r.mean);
  EXPECT_EQ(flip_mean(r, Mask{}), r.mean);
  EXPECT_NE(thrown_message([&] { flip_mean(r, Mask{20, 10, std::vector<std::uint8_t>(200, 0)}); }).find("selects no pixels"),
            std::string::npos);
  EXPECT_NE(thrown_message([&] { flip_mean(r, Mask{10, 20, std::vector<std::uint8_t>(200, 1)}); }).find("mask is 10x20"),
            std::string::npos);
}

TEST(FlipMap, MagmaEndsAndMonotoneBrightness) {
  FlipResult r;
  r.width = 101;
  r.height = 1;
  for (int i = 0; i <= 100; ++i) r.error.push_back(static_cast<float>(i) / 100.0f);
  const Image m = flip_error_map(r);
  ASSERT_EQ(m.width, 101);
  // magma runs from near black to pale yellow, each step brighter than the last.
  EXPECT_LT(std::max({m.rgb[0].r, m.rgb[0].g, m.rgb[0].b}), 0.02f);
  EXPECT_GT(m.rgb[100].g, 0.95f);
  EXPECT_GT(m.rgb[100].b, 0.7f);
  auto bright = [](const glm::vec3& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; };
  for (int i = 1; i <= 100; ++i) EXPECT_GT(bright(m.rgb[static_cast<std::size_t>(i)]), bright(m.rgb[static_cast<std::size_t>(i - 1)])) << i;
}

// ---------------------------------------------------------------------------------------------------
// Bad input.

TEST(FlipErrors, BadImagesAreErrorsNamingTheProblem) {
  const Image a(4, 3, glm::vec3(0.5f)), b(3, 4, glm::vec3(0.5f));
  for (auto* fn : {&flip_ldr, &flip_hdr}) {
    const std::string sizes = thrown_message([&] { fn(a, b, {}); });
    EXPECT_NE(sizes.find("test image 4x3, reference image 3x4"), std::string::npos) << sizes;
    EXPECT_NE(thrown_message([&] { fn(Image(), a, {}); }).find("test image is empty"), std::string::npos);
    EXPECT_NE(thrown_message([&] { fn(a, Image(), {}); }).find("reference image is empty"), std::string::npos);
    Image short_buffer = a;
    short_buffer.rgb.pop_back();
    EXPECT_NE(thrown_message([&] { fn(short_buffer, a, {}); }).find("pixel buffer holds 11"), std::string::npos);
    Image nan = a;
    nan.at(2, 1).g = std::numeric_limits<float>::quiet_NaN();
    const std::string nan_msg = thrown_message([&] { fn(nan, a, {}); });
    EXPECT_NE(nan_msg.find("test image has a non-finite value"), std::string::npos) << nan_msg;
    EXPECT_NE(nan_msg.find("channel G at pixel (2, 1)"), std::string::npos) << nan_msg;
    Image inf = a;
    inf.at(3, 2).b = std::numeric_limits<float>::infinity();
    EXPECT_NE(thrown_message([&] { fn(a, inf, {}); }).find("reference image has a non-finite value inf in channel B at pixel (3, 2)"),
              std::string::npos);
  }
  Image bright = a;
  bright.at(1, 0).r = 1.5f;
  const std::string range = thrown_message([&] { flip_ldr(bright, a); });
  EXPECT_NE(range.find("value 1.5 outside [0, 1] in channel R at pixel (1, 0)"), std::string::npos) << range;
  Image negative = a;
  negative.at(0, 2).b = -0.25f;
  EXPECT_NE(thrown_message([&] { flip_ldr(a, negative); }).find("reference image has a value -0.25 outside [0, 1]"),
            std::string::npos);
  EXPECT_NO_THROW(flip_hdr(bright, a));  // HDR takes any finite value
}

TEST(FlipErrors, BadOptionsAreErrors) {
  const Image a(6, 6, glm::vec3(0.5f));
  for (double ppd : {0.0, -67.0, 0.5, 1e6, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    FlipOptions opt;
    opt.ppd = ppd;
    EXPECT_NE(thrown_message([&] { flip_ldr(a, a, opt); }).find("pixels per degree (ppd) must be in [1, 1000]"),
              std::string::npos)
        << ppd;
    EXPECT_NE(thrown_message([&] { flip_hdr(a, a, opt); }).find("ppd"), std::string::npos) << ppd;
  }
  for (double ppd : {kFlipMinPpd, kFlipMaxPpd / 50}) {
    FlipOptions opt;
    opt.ppd = ppd;
    EXPECT_NO_THROW(flip_ldr(a, a, opt)) << ppd;
  }
  FlipOptions reversed;
  reversed.start_exposure = 2.0;
  reversed.stop_exposure = 1.0;
  EXPECT_NE(thrown_message([&] { flip_hdr(a, a, reversed); }).find("start exposure 2 is above stop exposure 1"),
            std::string::npos);
  FlipOptions nan_exposure;
  nan_exposure.start_exposure = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(thrown_message([&] { flip_hdr(a, a, nan_exposure); }).find("start exposure must be finite"), std::string::npos);
  FlipOptions huge_exposure;
  huge_exposure.stop_exposure = 1e4;
  EXPECT_NE(thrown_message([&] { flip_hdr(a, a, huge_exposure); }).find("stop exposure must be finite and within"),
            std::string::npos);
  for (int n : {-1, kFlipMaxExposures + 1}) {
    FlipOptions opt;
    opt.num_exposures = n;
    EXPECT_NE(thrown_message([&] { flip_hdr(a, a, opt); }).find("num_exposures must be in [0, 1024]"), std::string::npos) << n;
  }
  EXPECT_THROW(flip_pixels_per_degree(0.0, 0.7, 3840), std::invalid_argument);
  EXPECT_THROW(flip_pixels_per_degree(0.7, -0.7, 3840), std::invalid_argument);
  EXPECT_THROW(flip_pixels_per_degree(0.7, 0.7, 0), std::invalid_argument);
}

}  // namespace
}  // namespace softgi::metrics
