// Image-quality metrics on HDR images: RMSE, relMSE, PSNR, SSIM, error maps (docs/metrics.md).
#include "softgi/metrics/image_metrics.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace softgi::metrics {

namespace {

// Rec. 709 / sRGB luminance weights for linear RGB (the primaries every renderer here works in).
constexpr double kLumaR = 0.2126, kLumaG = 0.7152, kLumaB = 0.0722;

// SSIM, Wang, Bovik, Sheikh, Simoncelli 2004, "Image quality assessment: from error visibility to
// structural similarity", section III-B/C: K1, K2 (Eq. 7, 9), 11x11 Gaussian window with sigma 1.5
// samples (Eq. 14-16). L = 1 because SSIM runs on x / (1 + x), which maps [0, inf) onto [0, 1).
constexpr double kSsimK1 = 0.01, kSsimK2 = 0.03, kSsimL = 1.0;
constexpr double kSsimC1 = (kSsimK1 * kSsimL) * (kSsimK1 * kSsimL);
constexpr double kSsimC2 = (kSsimK2 * kSsimL) * (kSsimK2 * kSsimL);
constexpr double kSsimSigma = 1.5;
constexpr int kSsimRadius = 5;  // 11x11 window

// Default error-map scale: the 99th percentile, so that a few fireflies do not wash out the map.
constexpr std::size_t kErrorMapPercent = 99;

// Viridis (matplotlib) sampled at t = k/8, display-referred sRGB; interpolated linearly between stops.
constexpr std::array<std::array<int, 3>, 9> kViridis = {{{0x44, 0x01, 0x54},
                                                         {0x47, 0x2d, 0x7b},
                                                         {0x3b, 0x52, 0x8b},
                                                         {0x2c, 0x72, 0x8e},
                                                         {0x21, 0x91, 0x8c},
                                                         {0x28, 0xae, 0x80},
                                                         {0x5e, 0xc9, 0x62},
                                                         {0xad, 0xdc, 0x30},
                                                         {0xfd, 0xe7, 0x25}}};
// Signed map: the end colours of Moreland's cool-warm map (#3B4CC0, #B40426) through white.
constexpr std::array<int, 3> kSignedNegative = {0x3b, 0x4c, 0xc0};
constexpr std::array<int, 3> kSignedPositive = {0xb4, 0x04, 0x26};

std::string size_str(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void check_image(const Image& img, const char* role) {
  if (img.width <= 0 || img.height <= 0 || img.empty())
    throw std::invalid_argument(std::string(role) + " image is empty (" + size_str(img.width, img.height) + ")");
  const std::size_t n = static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height);
  if (img.rgb.size() != n)
    throw std::invalid_argument(std::string(role) + " image: pixel buffer holds " + std::to_string(img.rgb.size()) +
                                " pixels, expected " + size_str(img.width, img.height) + " = " + std::to_string(n));
}

// Row-major scan, so the error names the first bad pixel in reading order.
void check_finite(const Image& img, const char* role) {
  static const char* kChannel[3] = {"R", "G", "B"};
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const glm::vec3& p = img.at(x, y);
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(p[c])) {
          std::ostringstream os;
          os << role << " image has a non-finite value " << p[c] << " in channel " << kChannel[c] << " at pixel ("
             << x << ", " << y << ")";
          throw std::invalid_argument(os.str());
        }
    }
}

void check_pair(const Image& a, const Image& b) {
  check_image(a, "test");
  check_image(b, "reference");
  if (a.width != b.width || a.height != b.height)
    throw std::invalid_argument("image sizes differ: test image " + size_str(a.width, a.height) + ", reference image " +
                                size_str(b.width, b.height));
  check_finite(a, "test");
  check_finite(b, "reference");
}

// Per-pixel weight 0/1. A default Mask (no size, no data) counts every pixel.
std::vector<std::uint8_t> mask_weights(const Mask& mask, int w, int h) {
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  if (mask.width == 0 && mask.height == 0 && mask.on.empty()) return std::vector<std::uint8_t>(n, 1);
  if (mask.width != w || mask.height != h)
    throw std::invalid_argument("mask size " + size_str(mask.width, mask.height) + " differs from image size " +
                                size_str(w, h));
  if (mask.on.size() != n)
    throw std::invalid_argument("mask buffer holds " + std::to_string(mask.on.size()) + " values, expected " +
                                size_str(w, h) + " = " + std::to_string(n));
  std::vector<std::uint8_t> m(n);
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    m[i] = mask.on[i] != 0 ? 1 : 0;
    any = any || m[i];
  }
  if (!any) throw std::invalid_argument("mask selects no pixels (" + size_str(w, h) + ", all zero)");
  return m;
}

double luma(const glm::vec3& p) { return kLumaR * p.r + kLumaG * p.g + kLumaB * p.b; }

// x / (1 + x) for x >= 0; odd extension for negative values, so the map stays monotone and bounded.
double tone_map(double x) { return x / (1.0 + std::abs(x)); }

double ssim_luma(const glm::vec3& p) {
  return kLumaR * tone_map(p.r) + kLumaG * tone_map(p.g) + kLumaB * tone_map(p.b);
}

// Mean SSIM over counted pixels (Wang et al. 2004, Eq. 13 per window, Eq. 17 mean). Every window is the
// Gaussian restricted to counted pixels inside the image and renormalised (normalised convolution), so
// image borders and masked-out pixels never enter a statistic: a counted pixel's SSIM depends on counted
// pixels only. The window and its weights are separable, so two 1D passes give the exact 2D sums. Rows
// are processed in strips (parallel, each with its own horizontal-pass buffer) so that memory stays at
// two luminance planes plus one strip, and the strip sums are added in order so the result is deterministic.
double mean_ssim(const Image& a, const Image& b, const std::vector<std::uint8_t>& m) {
  const int w = a.width, h = a.height;
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::array<double, 2 * kSsimRadius + 1> g{};
  for (int k = -kSsimRadius; k <= kSsimRadius; ++k)
    g[k + kSsimRadius] = std::exp(-(k * k) / (2.0 * kSsimSigma * kSsimSigma));

  std::vector<double> lx(n), ly(n);
  for (std::size_t i = 0; i < n; ++i) {
    lx[i] = ssim_luma(a.rgb[i]);
    ly[i] = ssim_luma(b.rgb[i]);
  }

  // Strips of rows, each with its own buffers; planes are stored separately (structure of arrays) so the
  // 11-tap loops run over contiguous x and vectorise. Masked-out pixels enter as exact zeros (m in {0, 1}).
  constexpr int kStripRows = 32;
  constexpr int kPlanes = 6;  // m, m*x, m*y, m*x^2, m*y^2, m*x*y
  const int strips = (h + kStripRows - 1) / kStripRows;
  std::vector<double> strip_sum(static_cast<std::size_t>(strips), 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, strips, 1), [&](const tbb::blocked_range<int>& range) {
    std::array<std::vector<double>, kPlanes> row, hor, acc;
    for (int p = 0; p < kPlanes; ++p) {
      row[p].resize(static_cast<std::size_t>(w));
      acc[p].resize(static_cast<std::size_t>(w));
    }
    for (int s = range.begin(); s < range.end(); ++s) {
      const int y0 = s * kStripRows, y1 = std::min(h, y0 + kStripRows);
      const int t0 = std::max(0, y0 - kSsimRadius), t1 = std::min(h, y1 + kSsimRadius);
      for (auto& plane : hor) plane.assign(static_cast<std::size_t>(t1 - t0) * w, 0.0);
      // Horizontal pass over rows t0..t1 (the strip plus the vertical window's reach).
      for (int y = t0; y < t1; ++y) {
        const std::size_t base = static_cast<std::size_t>(y) * w;
        for (int x = 0; x < w; ++x) {
          const double mi = m[base + x], vx = lx[base + x], vy = ly[base + x];
          row[0][x] = mi;
          row[1][x] = mi * vx;
          row[2][x] = mi * vy;
          row[3][x] = mi * (vx * vx);
          row[4][x] = mi * (vy * vy);
          row[5][x] = mi * (vx * vy);  // brackets keep SSIM(a, b) == SSIM(b, a) bit for bit
        }
        for (int p = 0; p < kPlanes; ++p) {
          const double* in = row[p].data();
          double* out = &hor[p][static_cast<std::size_t>(y - t0) * w];
          for (int x = 0; x < w; ++x) {
            if (x >= kSsimRadius && x < w - kSsimRadius) {
              double tap_sum = 0.0;
              for (int k = -kSsimRadius; k <= kSsimRadius; ++k) tap_sum += g[k + kSsimRadius] * in[x + k];
              out[x] = tap_sum;
            } else {
              double tap_sum = 0.0;
              for (int k = std::max(-kSsimRadius, -x); k <= std::min(kSsimRadius, w - 1 - x); ++k)
                tap_sum += g[k + kSsimRadius] * in[x + k];
              out[x] = tap_sum;
            }
          }
        }
      }
      double sum = 0.0;
      for (int y = y0; y < y1; ++y) {
        const int klo = std::max(-kSsimRadius, -y), khi = std::min(kSsimRadius, h - 1 - y);
        for (int p = 0; p < kPlanes; ++p) {
          double* out = acc[p].data();
          std::fill(out, out + w, 0.0);
          for (int k = klo; k <= khi; ++k) {
            const double gk = g[k + kSsimRadius];
            const double* in = &hor[p][static_cast<std::size_t>(y + k - t0) * w];
            for (int x = 0; x < w; ++x) out[x] += gk * in[x];
          }
        }
        const std::size_t base = static_cast<std::size_t>(y) * w;
        for (int x = 0; x < w; ++x) {
          if (!m[base + x]) continue;
          // acc[0] >= g[centre] = 1 because the pixel itself is counted: no division by a tiny weight.
          const double wsum = acc[0][x];
          const double mx = acc[1][x] / wsum, my = acc[2][x] / wsum;
          const double sxx = acc[3][x] / wsum - mx * mx, syy = acc[4][x] / wsum - my * my;
          const double sxy = acc[5][x] / wsum - mx * my;
          sum += ((2.0 * (mx * my) + kSsimC1) * (2.0 * sxy + kSsimC2)) /
                 ((mx * mx + my * my + kSsimC1) * (sxx + syy + kSsimC2));
        }
      }
      strip_sum[static_cast<std::size_t>(s)] = sum;
    }
  });
  long long count = 0;
  for (std::uint8_t v : m) count += v;
  double sum = 0.0;
  for (double v : strip_sum) sum += v;
  return sum / static_cast<double>(count);
}

glm::vec3 to_unit(const std::array<int, 3>& c) { return glm::vec3(c[0], c[1], c[2]) / 255.0f; }

glm::vec3 viridis(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double s = t * static_cast<double>(kViridis.size() - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(s), kViridis.size() - 2);
  const float f = static_cast<float>(s - static_cast<double>(i));
  return to_unit(kViridis[i]) * (1.0f - f) + to_unit(kViridis[i + 1]) * f;
}

glm::vec3 cool_warm(double t) {
  t = std::clamp(t, -1.0, 1.0);
  const glm::vec3 white(1.0f);
  const glm::vec3 end = to_unit(t < 0 ? kSignedNegative : kSignedPositive);
  const float f = static_cast<float>(std::abs(t));
  return white * (1.0f - f) + end * f;
}

// Signed linear-luminance difference, test minus reference.
std::vector<double> luma_difference(const Image& a, const Image& b) {
  std::vector<double> d(a.rgb.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = luma(a.rgb[i]) - luma(b.rgb[i]);
  return d;
}

double effective_scale(const std::vector<double>& diff, double scale) {
  if (!std::isfinite(scale) || scale < 0.0) {
    std::ostringstream os;
    os << "error map scale must be finite and >= 0 (0 = 99th percentile), got " << scale;
    throw std::invalid_argument(os.str());
  }
  if (scale > 0.0) return scale;
  std::vector<double> e(diff.size());
  for (std::size_t i = 0; i < e.size(); ++i) e[i] = std::abs(diff[i]);
  // Nearest-rank percentile: the smallest error that at least 99% of the pixels do not exceed.
  // Integer arithmetic: ceil(0.99 n) in floating point can land one rank off.
  const std::size_t rank = (kErrorMapPercent * e.size() + 99) / 100;
  const std::size_t k = std::clamp<std::size_t>(rank, 1, e.size()) - 1;
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(k), e.end());
  double s = e[k];
  // Fewer than 1% of the pixels differ: fall back to the largest error, then to 1 (identical images).
  if (s <= 0.0) s = *std::max_element(e.begin(), e.end());
  if (s <= 0.0) s = 1.0;
  return s;
}

}  // namespace

Metrics compare(const Image& a, const Image& b, const Mask& mask, const MetricOptions& opt) {
  check_pair(a, b);
  if (!std::isfinite(opt.relmse_epsilon) || opt.relmse_epsilon <= 0.0) {
    std::ostringstream os;
    os << "relmse_epsilon must be finite and > 0, got " << opt.relmse_epsilon;
    throw std::invalid_argument(os.str());
  }
  if (!std::isfinite(opt.psnr_peak)) {
    std::ostringstream os;
    os << "psnr_peak must be finite (<= 0 selects the reference maximum), got " << opt.psnr_peak;
    throw std::invalid_argument(os.str());
  }
  const std::vector<std::uint8_t> m = mask_weights(mask, a.width, a.height);

  Metrics r;
  double se = 0.0, rel = 0.0, ref_max = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (!m[i]) continue;
    ++r.pixels;
    for (int c = 0; c < 3; ++c) {
      const double x = a.rgb[i][c], y = b.rgb[i][c], d = x - y;
      se += d * d;
      rel += d * d / (y * y + opt.relmse_epsilon);
      r.max_abs = std::max(r.max_abs, std::abs(d));
      ref_max = std::max(ref_max, y);
    }
  }
  const double samples = 3.0 * static_cast<double>(r.pixels);
  const double mse = se / samples;
  r.rmse = std::sqrt(mse);
  r.relmse = rel / samples;
  const double peak = opt.psnr_peak > 0.0 ? opt.psnr_peak : ref_max;
  // Identical images: +inf. A black reference with no given peak: 10 log10(0 / mse) = -inf.
  if (mse == 0.0) r.psnr = std::numeric_limits<double>::infinity();
  else if (peak <= 0.0) r.psnr = -std::numeric_limits<double>::infinity();
  else r.psnr = 10.0 * std::log10(peak * peak / mse);
  r.ssim = mean_ssim(a, b, m);
  return r;
}

double error_map_scale(const Image& a, const Image& b, double scale) {
  check_pair(a, b);
  return effective_scale(luma_difference(a, b), scale);
}

Image error_map(const Image& a, const Image& b, double scale) {
  check_pair(a, b);
  const std::vector<double> d = luma_difference(a, b);
  const double s = effective_scale(d, scale);
  Image out(a.width, a.height);
  for (std::size_t i = 0; i < d.size(); ++i) out.rgb[i] = viridis(std::abs(d[i]) / s);
  return out;
}

Image signed_error_map(const Image& a, const Image& b, double scale) {
  check_pair(a, b);
  const std::vector<double> d = luma_difference(a, b);
  const double s = effective_scale(d, scale);
  Image out(a.width, a.height);
  for (std::size_t i = 0; i < d.size(); ++i) out.rgb[i] = cool_warm(d[i] / s);
  return out;
}

}  // namespace softgi::metrics
