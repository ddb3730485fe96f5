// FLIP, a perceptual image-difference evaluator, and its HDR extension (docs/metrics.md#flip).
//   LDR-FLIP: Andersson, Nilsson, Akenine-Moller, Oskarsson, Astrom, Fairchild 2020, "FLIP: A Difference
//             Evaluator for Alternating Images".
//   HDR-FLIP: Andersson, Nilsson, Akenine-Moller 2021, "Visualizing and Communicating Errors in Rendered
//             Images" (Ray Tracing Gems II, chapter 19): the per-pixel maximum of LDR-FLIP over a range of
//             exposures of the tone-mapped images.
#pragma once

#include <numbers>
#include <optional>
#include <vector>

#include "softgi/image.hpp"

namespace softgi::metrics {

// Pixels per degree of visual angle for an observer `distance_m` from a display `display_width_m` wide
// showing `display_width_px` columns: distance * (px / width) * pi / 180, the FLIP papers' formula.
double flip_pixels_per_degree(double distance_m, double display_width_m, int display_width_px);

// The FLIP papers' default observer: 0.7 m from a 0.7 m wide 3840-pixel (4K) display, about 67 PPD.
inline constexpr double kFlipDefaultPpd = 0.7 * (3840.0 / 0.7) * std::numbers::pi / 180.0;
// Accepted PPD range. Below 1 the feature detectors' Gaussian (sigma = 0.041 PPD pixels) is narrower than
// a tenth of a pixel and its sampled weights underflow; above 1000 the filters span thousands of pixels.
inline constexpr double kFlipMinPpd = 1.0, kFlipMaxPpd = 1000.0;
// Accepted exposure compensations (log2 scale) and exposure counts for HDR-FLIP.
inline constexpr double kFlipMaxAbsExposure = 256.0;
inline constexpr int kFlipMaxExposures = 1024;

// The tone mappers HDR-FLIP can assume (the ACES fit is the papers' default).
enum class FlipToneMapper { aces, hable, reinhard };

struct FlipOptions {
  double ppd = kFlipDefaultPpd;
  // Keep the colour and feature terms (FlipResult::color_term / feature_term). flip_ldr only.
  bool keep_terms = false;
  // HDR-FLIP only. Exposures not given are computed from the reference; num_exposures = 0 selects
  // max(2, ceil(stop - start)).
  FlipToneMapper tone_mapper = FlipToneMapper::aces;
  std::optional<double> start_exposure, stop_exposure;
  int num_exposures = 0;
  // HDR-FLIP only. The automatic stop exposure log2(x / median) is undefined when at least half the
  // reference is black (a model against an empty background). false (the papers' rule): that is an error.
  // true: the median is taken over the pixels of positive luminance instead, and
  // FlipResult::stop_from_positive_median says so.
  bool positive_median_fallback = false;
};

struct FlipResult {
  int width = 0, height = 0;
  std::vector<float> error;  // per pixel, row-major, in [0, 1]
  double mean = 0.0;         // mean of `error`: the number usually reported as "FLIP"
  // With FlipOptions::keep_terms (flip_ldr): the redistributed colour difference deltaE_c and the feature
  // difference deltaE_f, error = deltaE_c ^ (1 - deltaE_f).
  std::vector<float> color_term, feature_term;
  // flip_hdr: the exposure range and the exposures evaluated (start + i * step), log2 scale.
  double start_exposure = 0.0, stop_exposure = 0.0;
  std::vector<double> exposures;
  bool stop_from_positive_median = false;
};

// LDR-FLIP of two sRGB-encoded images with values in [0, 1] (display-referred, e.g. read from PNG).
// Symmetric in its arguments. Throws std::invalid_argument for an empty image, different sizes, a NaN,
// infinite or out-of-[0, 1] value (naming the image, channel and pixel) and a PPD outside
// [kFlipMinPpd, kFlipMaxPpd].
FlipResult flip_ldr(const Image& test, const Image& reference, const FlipOptions& opt = {});

// HDR-FLIP of two linear HDR images; negative values count as 0. The exposure range comes from the
// reference (start: its largest luminance maps to 0.85 after tone mapping; stop: its median does).
// Throws std::invalid_argument as flip_ldr (values above 1 are allowed), and for start > stop, a
// non-finite exposure or one beyond +-kFlipMaxAbsExposure, num_exposures < 0 or > kFlipMaxExposures, and
// a reference whose median luminance is 0 but whose maximum is not, when no stop exposure is given and
// positive_median_fallback is off (the stop exposure log2(x / 0) would be infinite).
FlipResult flip_hdr(const Image& test, const Image& reference, const FlipOptions& opt = {});

// The mean of `error` over the pixels a mask selects (all when the mask is empty). The filters still see
// the whole image, so a masked pixel next to an unmasked edge keeps that edge's feature response.
double flip_mean(const FlipResult& r, const Mask& mask);

// FLIP's error map: `error` through the magma colour map (black = 0, pale yellow = 1), display-referred.
Image flip_error_map(const FlipResult& r);

}  // namespace softgi::metrics
