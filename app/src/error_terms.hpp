// The errors of a rendered image against a reference made of two independent halves, as `softgi
// compare` and `softgi report` record them (docs/reports.md, "How each number is measured").
#pragma once

#include <nlohmann/json.hpp>

#include "softgi/image.hpp"
#include "softgi/metrics/flip.hpp"

namespace softgi::app {

// relMSE with the reference's noise removed (`relmse`), the uncorrected value (`relmse_raw`), the
// noise term removed, its 95 % interval (`ci_low`, `ci_high`), `below_noise_floor`, SSIM, HDR-FLIP,
// RMSE, PSNR and the largest difference against the mean of the halves, over the surface pixels. FLIP takes the median of the lit
// pixels for its stop exposure where at least half the reference is black (mostly dark indirect
// images), and is null where the reference is all black. An empty test image gives null. The FLIP
// result itself goes to *flip_out when asked for (for its map).
nlohmann::ordered_json noise_corrected_errors(const Image& test, const Image& half_a, const Image& half_b, const Mask& surface,
                                              metrics::FlipResult* flip_out = nullptr);

}  // namespace softgi::app
