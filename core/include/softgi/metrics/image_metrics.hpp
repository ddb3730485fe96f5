// Image-quality metrics on HDR images (docs/metrics.md).
#pragma once

#include <string>

#include "softgi/image.hpp"

namespace softgi::metrics {

struct MetricOptions {
  // relMSE = mean over pixels and channels of (a - b)^2 / (b^2 + epsilon), b the reference.
  double relmse_epsilon = 1e-2;
  // PSNR peak: the reference's max channel value when <= 0 (HDR), else this value.
  double psnr_peak = 0.0;
};
struct Metrics {
  double rmse = 0, relmse = 0, psnr = 0, ssim = 0;
  double max_abs = 0;
  long long pixels = 0;  // pixels counted (mask applied)
};

// a = test image, b = reference. Sizes must match (std::invalid_argument naming both sizes); NaN/Inf
// pixels are an error naming the first such pixel. SSIM on luminance, Gaussian window sigma 1.5,
// standard constants, on tone-mapped values x / (1 + x) so HDR ranges do not dominate.
Metrics compare(const Image& a, const Image& b, const Mask& mask = {}, const MetricOptions& opt = {});

// False-colour map of |a - b| (luminance), normalised by `scale` (0: the 99th percentile), viridis-like.
Image error_map(const Image& a, const Image& b, double scale = 0.0);
// The scale error_map would use for these images (the given one, or the 99th percentile).
double error_map_scale(const Image& a, const Image& b, double scale = 0.0);
// Signed map of luma(a) - luma(b): white at 0, blue where a is darker, red where brighter.
Image signed_error_map(const Image& a, const Image& b, double scale = 0.0);

}  // namespace softgi::metrics
