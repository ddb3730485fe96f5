#include "error_terms.hpp"

#include <cmath>
#include <stdexcept>

#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"

namespace softgi::app {

namespace {
nlohmann::ordered_json number_or_null(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }
}  // namespace

nlohmann::ordered_json noise_corrected_errors(const Image& test, const Image& half_a, const Image& half_b, const Mask& surface,
                                              metrics::FlipResult* flip_out) {
  if (test.empty()) return nullptr;
  const double eps = metrics::MetricOptions{}.relmse_epsilon;
  const metrics::NoiseCorrectedError e = metrics::noise_corrected_relmse(test, half_a, half_b, surface, eps);
  const Image mean = metrics::mean_of_halves(half_a, half_b);
  const metrics::Metrics m = metrics::compare(test, mean, surface);
  metrics::FlipOptions fo;
  fo.positive_median_fallback = true;
  double flip = std::nan("");
  try {
    metrics::FlipResult fr = metrics::flip_hdr(test, mean, fo);
    flip = metrics::flip_mean(fr, surface);
    if (flip_out) *flip_out = std::move(fr);
  } catch (const std::invalid_argument&) {
    // An all-black reference component has no exposure range: FLIP is undefined there.
  }
  return {{"relmse", e.corrected},          {"relmse_raw", e.raw},    {"noise", e.noise},
          {"ci_low", e.ci_low},             {"ci_high", e.ci_high},   {"below_noise_floor", e.below_noise_floor()},
          {"ssim", number_or_null(m.ssim)}, {"flip", number_or_null(flip)}, {"rmse", m.rmse},
          {"psnr", std::isfinite(m.psnr) ? nlohmann::ordered_json(m.psnr) : nlohmann::ordered_json("inf")},
          {"max_abs", m.max_abs},           {"pixels", m.pixels}};
}

}  // namespace softgi::app
