// Errors against a Monte Carlo reference with its own noise removed, from two independent halves.
#include "softgi/metrics/reference_noise.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace softgi::metrics {

namespace {

// Two-sided 95 % quantile of the normal distribution: the per-pixel terms are many and independent.
constexpr double kZ95 = 1.959963984540054;
// Below this share of the corrected error the reference's noise no longer matters for it.
constexpr double kNoiseFloorShare = 0.1;

void check(const Image& img, const Image& like, const char* role) {
  const std::string size = std::to_string(img.width) + "x" + std::to_string(img.height);
  if (img.width <= 0 || img.height <= 0 || img.rgb.size() != static_cast<std::size_t>(img.width) * img.height)
    throw std::invalid_argument(std::string(role) + " image is empty or its buffer does not match its size " + size);
  if (img.width != like.width || img.height != like.height)
    throw std::invalid_argument(std::string(role) + " image is " + size + ", the test image " + std::to_string(like.width) + "x" +
                                std::to_string(like.height));
  for (std::size_t i = 0; i < img.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(img.rgb[i][c]))
        throw std::invalid_argument(std::string(role) + " image has a non-finite value at pixel (" + std::to_string(i % img.width) +
                                    ", " + std::to_string(i / img.width) + ")");
}

}  // namespace

bool NoiseCorrectedError::below_noise_floor() const { return ci_low <= 0.0 || noise > kNoiseFloorShare * corrected; }

Image mean_of_halves(const Image& a, const Image& b) {
  check(a, a, "first half");
  check(b, a, "second half");
  Image r(a.width, a.height);
  for (std::size_t i = 0; i < r.rgb.size(); ++i) r.rgb[i] = 0.5f * (a.rgb[i] + b.rgb[i]);
  return r;
}

namespace {

// Mean, noise-corrected mean and 95 % interval of per-pixel terms e - s (e: the raw term, s: what the
// noise adds to it), summed over the pixels the mask selects.
struct Accumulator {
  double raw = 0.0, noise = 0.0, sq = 0.0;
  long long pixels = 0;
  void add(double e, double s) {
    raw += e;
    noise += s;
    sq += (e - s) * (e - s);
    ++pixels;
  }
  NoiseCorrectedError result() const {
    if (pixels == 0) throw std::invalid_argument("mask selects no pixels");
    NoiseCorrectedError out;
    out.pixels = pixels;
    out.raw = raw / pixels;
    out.noise = noise / pixels;
    out.corrected = out.raw - out.noise;
    const double var = pixels > 1 ? (sq / pixels - out.corrected * out.corrected) * pixels / (pixels - 1) : 0.0;
    const double half_width = kZ95 * std::sqrt(std::max(0.0, var) / pixels);
    out.ci_low = out.corrected - half_width;
    out.ci_high = out.corrected + half_width;
    return out;
  }
};

// Whether pixel i counts (an empty mask selects every pixel); throws for a mask of another size.
bool mask_check(const Mask& mask, const Image& t, double epsilon) {
  if (!(epsilon > 0.0) || !std::isfinite(epsilon))
    throw std::invalid_argument("relMSE epsilon must be finite and > 0, got " + std::to_string(epsilon));
  const bool masked = !(mask.width == 0 && mask.height == 0 && mask.on.empty());
  if (masked && (mask.width != t.width || mask.height != t.height || mask.on.size() != t.rgb.size()))
    throw std::invalid_argument("mask is " + std::to_string(mask.width) + "x" + std::to_string(mask.height) + ", the images " +
                                std::to_string(t.width) + "x" + std::to_string(t.height));
  return masked;
}

// The estimate of noise_corrected_relmse, and of noise_corrected_relmse_between when the test's halves
// ta and tb are given (t is then their mean, and their noise is taken out as the reference's is).
NoiseCorrectedError corrected_relmse(const Image& t, const Image* ta, const Image* tb, const Image& a, const Image& b,
                                     const Mask& mask, double epsilon) {
  const bool masked = mask_check(mask, t, epsilon);
  // Per pixel, the mean of its three channels' terms: the channels of one pixel share its samples, so
  // the pixels, not the channels, are the independent draws the interval counts.
  Accumulator acc;
  for (std::size_t i = 0; i < t.rgb.size(); ++i) {
    if (masked && !mask.on[i]) continue;
    double e = 0.0, s = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double r = 0.5 * (static_cast<double>(a.rgb[i][c]) + b.rgb[i][c]);
      const double w = 1.0 / (r * r + epsilon);
      const double d = t.rgb[i][c] - r, half = 0.5 * (static_cast<double>(a.rgb[i][c]) - b.rgb[i][c]);
      e += d * d * w / 3.0;
      s += half * half * w / 3.0;
      if (ta) {
        const double test_half = 0.5 * (static_cast<double>(ta->rgb[i][c]) - tb->rgb[i][c]);
        s += test_half * test_half * w / 3.0;
      }
    }
    acc.add(e, s);
  }
  return acc.result();
}

}  // namespace

NoiseCorrectedError noise_corrected_relmse(const Image& t, const Image& a, const Image& b, const Mask& mask, double epsilon) {
  check(t, t, "test");
  check(a, t, "first half");
  check(b, t, "second half");
  return corrected_relmse(t, nullptr, nullptr, a, b, mask, epsilon);
}

NoiseCorrectedError noise_corrected_relmse_between(const Image& ta, const Image& tb, const Image& a, const Image& b,
                                                   const Mask& mask, double epsilon) {
  check(ta, ta, "test's first half");
  check(tb, ta, "test's second half");
  check(a, ta, "first half");
  check(b, ta, "second half");
  return corrected_relmse(mean_of_halves(ta, tb), &ta, &tb, a, b, mask, epsilon);
}

NoiseCorrectedError temporal_error(const Image& t0, const Image& t1, const Image& a0, const Image& b0, const Image& a1,
                                   const Image& b1, const Mask& mask, double epsilon) {
  check(t0, t0, "first frame's test");
  check(t1, t0, "second frame's test");
  check(a0, t0, "first frame's first half");
  check(b0, t0, "first frame's second half");
  check(a1, t0, "second frame's first half");
  check(b1, t0, "second frame's second half");
  const bool masked = mask_check(mask, t0, epsilon);
  Accumulator acc;
  for (std::size_t i = 0; i < t0.rgb.size(); ++i) {
    if (masked && !mask.on[i]) continue;
    double e = 0.0, s = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double r0 = 0.5 * (static_cast<double>(a0.rgb[i][c]) + b0.rgb[i][c]);
      const double r1 = 0.5 * (static_cast<double>(a1.rgb[i][c]) + b1.rgb[i][c]);
      const double w = 1.0 / (r0 * r0 + epsilon);
      const double d = (static_cast<double>(t1.rgb[i][c]) - t0.rgb[i][c]) - (r1 - r0);
      const double h0 = 0.5 * (static_cast<double>(a0.rgb[i][c]) - b0.rgb[i][c]);
      const double h1 = 0.5 * (static_cast<double>(a1.rgb[i][c]) - b1.rgb[i][c]);
      e += d * d * w / 3.0;
      s += (h0 * h0 + h1 * h1) * w / 3.0;
    }
    acc.add(e, s);
  }
  return acc.result();
}

}  // namespace softgi::metrics
