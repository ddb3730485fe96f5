// Errors against a noisy Monte Carlo reference with the reference's own noise taken out
// (docs/metrics.md, "Reference noise").
#pragma once

#include "softgi/image.hpp"

namespace softgi::metrics {

// The reference is the mean r = (a + b) / 2 of two independent halves a and b (the same renderer and
// sample count, independent seeds). Per pixel and channel, r = m + e with m the converged value and
// e its noise (variance s^2, independent of the test image t): E[(t - r)^2] = (t - m)^2 + s^2, and
// (a - b)^2 / 4 is an unbiased estimate of s^2 (var(a - b) = 2 var(a) = 4 s^2). So
//   raw       = mean (t - r)^2 / (r^2 + eps)                      (relMSE against r)
//   noise     = mean ((a - b)^2 / 4) / (r^2 + eps)                (what r's noise adds to raw)
//   corrected = raw - noise                                      (relMSE against m, estimated)
// with a 95 % confidence interval of `corrected` from the spread of its per-pixel terms (pixels are
// independent: every pixel draws its own samples; a pixel's channels are not, so its term is their
// mean). The weights 1 / (r^2 + eps) use the noisy r, as relMSE does.
struct NoiseCorrectedError {
  double raw = 0.0, noise = 0.0, corrected = 0.0;
  double ci_low = 0.0, ci_high = 0.0;  // 95 % interval of `corrected`
  long long pixels = 0;                // pixels counted
  // The reference cannot resolve this error: the interval reaches 0, or the reference's noise is
  // more than 10 % of the corrected error.
  bool below_noise_floor() const;
};
// Throws std::invalid_argument naming the image (test, first half, second half) that is empty,
// non-finite or of another size, a mask of another size or selecting nothing, or a bad epsilon.
NoiseCorrectedError noise_corrected_relmse(const Image& test, const Image& half_a, const Image& half_b, const Mask& mask = {},
                                           double epsilon = 1e-2);

// Both images noisy: the test is the mean t = (ta + tb) / 2 of two independent halves as well (one
// reference against another, as an error budget compares them). Its noise adds to raw as the
// reference's does, and is taken out the same way: noise = mean ((a - b)^2 / 4 + (ta - tb)^2 / 4) /
// (r^2 + eps), corrected = raw - noise. Errors name the image as noise_corrected_relmse's do.
NoiseCorrectedError noise_corrected_relmse_between(const Image& test_a, const Image& test_b, const Image& half_a,
                                                   const Image& half_b, const Mask& mask = {}, double epsilon = 1e-2);

// Temporal error of a frame sequence's step k -> k + 1: how far a test's frame-to-frame change
// t1 - t0 departs from the reference's r1 - r0, each reference frame the mean of two independent
// halves (a0, b0 and a1, b1, with seeds of their own): mean over pixels of the channels'
// ((t1 - t0) - (r1 - r0))^2 / (r0^2 + epsilon), less what the references' noise adds
// (((a0 - b0)^2 + (a1 - b1)^2) / 4 at the same weights), with the 95 % interval. A test whose error is
// the same in both frames scores 0 however large that error; flicker scores above 0. Errors name the
// image as noise_corrected_relmse's do.
NoiseCorrectedError temporal_error(const Image& t0, const Image& t1, const Image& a0, const Image& b0, const Image& a1,
                                   const Image& b1, const Mask& mask = {}, double epsilon = 1e-2);

// The two halves' mean, the reference they stand for.
Image mean_of_halves(const Image& half_a, const Image& half_b);

}  // namespace softgi::metrics
