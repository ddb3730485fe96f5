// sh::project_latlong at every map size: closed forms for constant maps, and a brute-force 2D
// quadrature of the documented reconstructions (box and bilinear) for single texels and random maps.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <utility>
#include <vector>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

using namespace softgi::sh;

namespace {

constexpr int kOrder = kMaxOrder;  // every band the library offers
// Exact integration in double: sums of at most a few thousand terms of size <= 4 pi plus an SH
// rotation, each rounding at ~1e-16 relative; 1e-12 leaves three orders of headroom.
constexpr double kExactTol = 1e-12;

// The sizes where centre sampling fails (1x1, 2x1, 4x2), an odd one (3x5) and a fine one (64x32).
const std::vector<std::pair<int, int>> kSizes = {{1, 1}, {2, 1}, {4, 2}, {3, 5}, {64, 32}};

// The reconstructions as docs/sh.md and sh.hpp describe them, written independently of the library:
// `pixel(u, v)` is the map; theta from +y, phi as sh::latlong_direction.
double nearest(const std::function<double(int, int)>& pixel, int w, int h, double theta, double phi) {
  const int u = std::clamp(static_cast<int>(std::floor(phi / (2.0 * kPi) * w)), 0, w - 1);
  const int v = std::clamp(static_cast<int>(std::floor(theta / kPi * h)), 0, h - 1);
  return pixel(u, v);
}
double bilinear(const std::function<double(int, int)>& pixel, int w, int h, double theta, double phi) {
  const double x = phi / (2.0 * kPi) * w - 0.5, y = theta / kPi * h - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const double fx = x - x0, fy = y - y0;
  const int u0 = ((static_cast<int>(x0) % w) + w) % w, u1 = (u0 + 1) % w;
  const int v0 = std::clamp(static_cast<int>(y0), 0, h - 1), v1 = std::clamp(static_cast<int>(y0) + 1, 0, h - 1);
  return (1 - fy) * ((1 - fx) * pixel(u0, v0) + fx * pixel(u1, v0)) + fy * ((1 - fx) * pixel(u0, v1) + fx * pixel(u1, v1));
}

// int f(d) y_lm(d) dd by a 2D Gauss-Legendre product in (theta, phi) with dd = sin(theta) dtheta dphi,
// evaluating the basis at the true direction d (no separation, no rotation). Panels break at every
// half texel (so both reconstructions are smooth inside each) and are at most pi/16 long; 16 nodes per
// panel then integrate the smooth trigonometric integrand (degree <= 8) to double rounding. Inside a
// panel either reconstruction is bilinear in (theta, phi), so a panel whose four corners read 0 holds
// none of f and is skipped (this keeps a single texel of a 64x32 map fast).
std::vector<double> brute_force(int w, int h, const std::function<double(double, double)>& f) {
  const GaussLegendre& gl = gauss_legendre(16);
  auto panels = [](double length, int halves) {
    std::vector<std::pair<double, double>> out;
    const double step = length / (2.0 * halves);
    const int sub = std::max(1, static_cast<int>(std::ceil(step / (kPi / 16))));
    for (int i = 0; i < 2 * halves; ++i)
      for (int k = 0; k < sub; ++k) out.push_back({step * (i + double(k) / sub), step * (i + double(k + 1) / sub)});
    return out;
  };
  std::vector<double> out(num_coeffs(kOrder), 0.0);
  std::array<double, kMaxCoeffs> y{};
  for (const auto& [t0, t1] : panels(kPi, h))
    for (const auto& [p0, p1] : panels(2.0 * kPi, w)) {
      const double et = 1e-9 * (t1 - t0), ep = 1e-9 * (p1 - p0);  // corners just inside the panel
      if (f(t0 + et, p0 + ep) == 0.0 && f(t0 + et, p1 - ep) == 0.0 && f(t1 - et, p0 + ep) == 0.0 && f(t1 - et, p1 - ep) == 0.0)
        continue;
      for (int i = 0; i < 16; ++i)
        for (int j = 0; j < 16; ++j) {
          const double theta = t0 + (t1 - t0) * 0.5 * (gl.nodes[i] + 1), phi = p0 + (p1 - p0) * 0.5 * (gl.nodes[j] + 1);
          const double wgt = 0.25 * (t1 - t0) * (p1 - p0) * gl.weights[i] * gl.weights[j] * std::sin(theta);
          const double st = std::sin(theta);
          eval_basis(kOrder, Vec3<double>{st * std::cos(phi), std::cos(theta), -st * std::sin(phi)}, y.data());
          const double v = f(theta, phi) * wgt;
          for (int k = 0; k < num_coeffs(kOrder); ++k) out[k] += v * y[k];
        }
    }
  return out;
}

std::vector<float> constant_map(int w, int h, const std::array<float, 3>& c) {
  std::vector<float> img;
  for (int k = 0; k < w * h; ++k) img.insert(img.end(), c.begin(), c.end());
  return img;
}

const char* name(LatLongFilter f) { return f == LatLongFilter::Nearest ? "nearest" : "bilinear"; }

}  // namespace

TEST(LatLongProjection, ConstantMapsGiveTheClosedFormAtEverySize) {
  const std::array<float, 3> c = {1.0f, 0.25f, 3.0f};
  for (LatLongFilter filter : {LatLongFilter::Nearest, LatLongFilter::Bilinear})
    for (const auto& [w, h] : kSizes) {
      const std::vector<float> img = constant_map(w, h, c);
      const std::vector<double> L = project_latlong(kOrder, img.data(), w, h, 3, filter);
      for (int ch = 0; ch < 3; ++ch) {
        // c times the projection of 1: (sqrt(4 pi), 0, ...), sqrt(4 pi) = 2 sqrt(pi).
        EXPECT_NEAR(L[ch * 64], 2.0 * std::sqrt(kPi) * c[ch], kExactTol * c[ch]) << w << "x" << h << " " << name(filter);
        for (int i = 1; i < 64; ++i)
          EXPECT_NEAR(L[ch * 64 + i], 0.0, kExactTol * c[ch]) << w << "x" << h << " " << name(filter) << " coefficient " << i;
      }
    }
}

// A constant map's irradiance pi c at every normal, through the clamped-cosine convolution: the
// band-1 and band-2 coefficients that centre sampling left on tiny maps would tilt it.
TEST(LatLongProjection, ConstantMapIrradianceIsPiEverywhere) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  for (const auto& [w, h] : kSizes) {
    const std::vector<float> img = constant_map(w, h, {2.0f, 2.0f, 2.0f});
    std::vector<double> L = project_latlong(3, img.data(), w, h, 3);
    std::vector<double> E(9);
    irradiance_env(3, L.data(), E.data());
    for (int t = 0; t < 50; ++t) {
      const Vec3<double> n = normalize(Vec3<double>{g(rng), g(rng), g(rng)});
      EXPECT_NEAR(reconstruct(3, E.data(), n), kPi * 2.0, kExactTol * 10.0) << w << "x" << h;
    }
  }
}

// One bright texel: with the box filter its coefficients are int over the texel's spherical
// rectangle of y_lm; with the bilinear filter, the integral of its tent. Pole rows and the wrap
// column included.
TEST(LatLongProjection, SingleTexelMatchesBruteForceIntegral) {
  struct Case {
    int w, h, u, v;
  };
  const std::vector<Case> cases = {{1, 1, 0, 0}, {2, 1, 1, 0}, {4, 2, 0, 0}, {4, 2, 3, 1}, {3, 5, 1, 2},
                                   {3, 5, 2, 4}, {8, 4, 5, 0}, {64, 32, 17, 9}};
  constexpr float kValue = 5.0f;
  for (LatLongFilter filter : {LatLongFilter::Nearest, LatLongFilter::Bilinear})
    for (const Case& cs : cases) {
      std::vector<float> img(static_cast<std::size_t>(cs.w) * cs.h, 0.0f);
      img[static_cast<std::size_t>(cs.v) * cs.w + cs.u] = kValue;
      const std::vector<double> L = project_latlong(kOrder, img.data(), cs.w, cs.h, 1, filter);
      auto pixel = [&](int u, int v) { return double(img[static_cast<std::size_t>(v) * cs.w + u]); };
      const std::vector<double> ref = brute_force(cs.w, cs.h, [&](double theta, double phi) {
        return filter == LatLongFilter::Nearest ? nearest(pixel, cs.w, cs.h, theta, phi) : bilinear(pixel, cs.w, cs.h, theta, phi);
      });
      if (filter == LatLongFilter::Nearest) {
        // y_00 over the rectangle: its exact solid angle (phi1 - phi0)(cos theta0 - cos theta1) / sqrt(4 pi).
        const double omega = 2.0 * kPi / cs.w * (std::cos(kPi * cs.v / cs.h) - std::cos(kPi * (cs.v + 1) / cs.h));
        EXPECT_NEAR(L[0], kValue * omega / (2.0 * std::sqrt(kPi)), kExactTol * kValue);
      }
      for (int i = 0; i < 64; ++i)
        EXPECT_NEAR(L[i], ref[i], kExactTol * kValue)
            << cs.w << "x" << cs.h << " texel (" << cs.u << ", " << cs.v << ") " << name(filter) << " coefficient " << i;
    }
}

TEST(LatLongProjection, RandomMapsMatchBruteForceIntegral) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  for (LatLongFilter filter : {LatLongFilter::Nearest, LatLongFilter::Bilinear})
    for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {1, 3}, {4, 2}, {3, 5}, {7, 4}}) {
      std::vector<float> img(static_cast<std::size_t>(w) * h * 2);
      for (float& x : img) x = u01(rng);
      const std::vector<double> L = project_latlong(kOrder, img.data(), w, h, 2, filter);
      for (int ch = 0; ch < 2; ++ch) {
        auto pixel = [&](int u, int v) { return double(img[(static_cast<std::size_t>(v) * w + u) * 2 + ch]); };
        const std::vector<double> ref = brute_force(w, h, [&](double theta, double phi) {
          return filter == LatLongFilter::Nearest ? nearest(pixel, w, h, theta, phi) : bilinear(pixel, w, h, theta, phi);
        });
        for (int i = 0; i < 64; ++i)
          EXPECT_NEAR(L[ch * 64 + i], ref[i], kExactTol) << w << "x" << h << " " << name(filter) << " channel " << ch << " coefficient " << i;
      }
    }
}
