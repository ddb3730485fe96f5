// Basis, quadrature, ZH rules, windowing, projection: closed forms and brute-force references.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

using namespace softgi::sh;

namespace {
// Double-precision closed forms agree to rounding: a few ulps of O(1) values.
constexpr double kClosedFormTol = 1e-13;
// Exact quadrature of band-limited integrands in double: rounding over ~1e3 nodes.
constexpr double kQuadratureTol = 1e-12;
// float evaluation against double: float epsilon (1.2e-7) times the recurrence's growth (~30 at l=7).
constexpr double kFloatTol = 5e-6;

Vec3<double> random_dir(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return normalize(Vec3<double>{n(rng), n(rng), n(rng)});
}
}  // namespace

TEST(ShBasis, ClosedFormsUpToBand3) {
  std::mt19937 rng(1);
  const double pi = kPi;
  for (int t = 0; t < 100; ++t) {
    auto s = random_dir(rng);
    double x = s.x, y = s.y, z = s.z;
    double e[16] = {
        0.5 * std::sqrt(1 / pi),
        std::sqrt(3 / (4 * pi)) * y, std::sqrt(3 / (4 * pi)) * z, std::sqrt(3 / (4 * pi)) * x,
        0.5 * std::sqrt(15 / pi) * x * y, 0.5 * std::sqrt(15 / pi) * y * z,
        0.25 * std::sqrt(5 / pi) * (3 * z * z - 1), 0.5 * std::sqrt(15 / pi) * x * z,
        0.25 * std::sqrt(15 / pi) * (x * x - y * y),
        0.25 * std::sqrt(35 / (2 * pi)) * y * (3 * x * x - y * y), 0.5 * std::sqrt(105 / pi) * x * y * z,
        0.25 * std::sqrt(21 / (2 * pi)) * y * (5 * z * z - 1), 0.25 * std::sqrt(7 / pi) * z * (5 * z * z - 3),
        0.25 * std::sqrt(21 / (2 * pi)) * x * (5 * z * z - 1), 0.25 * std::sqrt(105 / pi) * z * (x * x - y * y),
        0.25 * std::sqrt(35 / (2 * pi)) * x * (x * x - 3 * y * y)};
    double v[16];
    eval_basis(4, s, v);
    for (int i = 0; i < 16; ++i) EXPECT_NEAR(v[i], e[i], kClosedFormTol) << "index " << i;
  }
}

TEST(ShBasis, OrthonormalByQuadrature) {
  for (int order : {2, 5, 8}) {
    // Products of two band-(n-1) functions have degree 2n-2: n bands integrate them exactly.
    SphereQuadrature q = make_sphere_quadrature(order + 1);
    const int n2 = num_coeffs(order);
    std::vector<double> gram(n2 * n2, 0.0);
    double y[kMaxCoeffs];
    for (std::size_t k = 0; k < q.dirs.size(); ++k) {
      eval_basis(order, q.dirs[k], y);
      for (int i = 0; i < n2; ++i)
        for (int j = 0; j < n2; ++j) gram[i * n2 + j] += q.weights[k] * y[i] * y[j];
    }
    for (int i = 0; i < n2; ++i)
      for (int j = 0; j < n2; ++j) EXPECT_NEAR(gram[i * n2 + j], i == j ? 1.0 : 0.0, kQuadratureTol) << order << " " << i << " " << j;
  }
}

TEST(ShBasis, FloatMatchesDouble) {
  std::mt19937 rng(2);
  for (int t = 0; t < 200; ++t) {
    auto s = random_dir(rng);
    double yd[kMaxCoeffs];
    float yf[kMaxCoeffs];
    eval_basis(8, s, yd);
    eval_basis(8, Vec3<float>{float(s.x), float(s.y), float(s.z)}, yf);
    for (int i = 0; i < 64; ++i) EXPECT_NEAR(yf[i], yd[i], kFloatTol * std::max(1.0, std::abs(yd[i])));
  }
}

TEST(ShBasis, PolesAreFinite) {
  double y[kMaxCoeffs];
  for (double z : {1.0, -1.0}) {
    eval_basis(8, Vec3<double>{0, 0, z}, y);
    for (int l = 0; l < 8; ++l)
      for (int m = -l; m <= l; ++m) {
        ASSERT_TRUE(std::isfinite(y[index(l, m)]));
        if (m != 0) EXPECT_EQ(y[index(l, m)], 0.0);
        else EXPECT_NEAR(y[index(l, 0)], std::sqrt((2 * l + 1) / (4 * kPi)) * std::pow(z, l), kClosedFormTol);
      }
  }
}

TEST(GaussLegendre, IntegratesPolynomialsExactly) {
  for (int n : {1, 2, 5, 24, 64}) {
    const auto& gl = gauss_legendre(n);
    for (int d = 0; d <= 2 * n - 1; ++d) {
      double s = 0;
      for (int i = 0; i < n; ++i) s += gl.weights[i] * std::pow(gl.nodes[i], d);
      double exact = d % 2 ? 0.0 : 2.0 / (d + 1);
      EXPECT_NEAR(s, exact, kQuadratureTol) << "n=" << n << " degree " << d;
    }
  }
  EXPECT_THROW(gauss_legendre(0), std::invalid_argument);
}

TEST(GaussLegendre, GradedPanelsResolveAKink) {
  // int_0^1 x / sqrt(c^2 + x^2) dx = sqrt(1 + c^2) - c: a kink of width c at 0.
  for (double c : {1e-1, 1e-3, 1e-6}) {
    double exact = std::sqrt(1 + c * c) - c;
    double graded = integrate([&](double x) { return x / std::sqrt(c * c + x * x); }, 0.0, 1.0, 24, c);
    EXPECT_NEAR(graded, exact, 1e-12) << c;  // graded panels: rounding-level accuracy
  }
}

TEST(ZonalHarmonics, ClampedCosineClosedForm) {
  auto g = clamped_cosine_zh(8);
  const double pi = kPi;
  EXPECT_NEAR(g[0], std::sqrt(pi) / 2, kClosedFormTol);
  EXPECT_NEAR(g[1], std::sqrt(pi / 3), kClosedFormTol);
  EXPECT_NEAR(g[2], std::sqrt(5 * pi) / 8, kClosedFormTol);
  EXPECT_NEAR(g[3], 0.0, kClosedFormTol);
  EXPECT_NEAR(g[5], 0.0, kClosedFormTol);
  EXPECT_NEAR(g[7], 0.0, kClosedFormTol);
  // even l >= 2: 2 pi K_l int_0^1 mu P_l = 2 pi K_l (-1)^(l/2+1) (l-2)! / (2^l (l/2-1)! (l/2+1)!)
  for (int l : {4, 6}) {
    double fact = [](int k) { double f = 1; for (int i = 2; i <= k; ++i) f *= i; return f; }(l - 2);
    double f1 = 1, f2 = 1;
    for (int i = 2; i <= l / 2 - 1; ++i) f1 *= i;
    for (int i = 2; i <= l / 2 + 1; ++i) f2 *= i;
    double integral = ((l / 2 + 1) % 2 ? -1.0 : 1.0) * fact / (std::pow(2.0, l) * f1 * f2);
    EXPECT_NEAR(g[l], 2 * pi * std::sqrt((2 * l + 1) / (4 * pi)) * integral, kClosedFormTol) << l;
  }
}

TEST(ZonalHarmonics, RotationRuleMatchesProjection) {
  // A ZH rotated to axis d equals the projection of the same profile turned to d.
  std::mt19937 rng(3);
  const int order = 6;
  SphereQuadrature q = make_sphere_quadrature(order + 8);
  auto profile = [](double mu) { return std::exp(2 * mu) + mu * mu * mu; };
  // ZH of the profile about z, by 1D quadrature (the profile is not band-limited, but projection
  // commutes with rotation, so both sides carry the same truncation).
  std::vector<double> zh = project(order, q, [&](const Vec3<double>& s) { return profile(s.z); });
  std::vector<double> zh_bands(order);
  for (int l = 0; l < order; ++l) zh_bands[l] = zh[index(l, 0)];
  for (int t = 0; t < 5; ++t) {
    auto d = random_dir(rng);
    std::vector<double> rotated(num_coeffs(order));
    zh_rotate(order, zh_bands.data(), d, rotated.data());
    auto direct = project(order, q, [&](const Vec3<double>& s) { return profile(dot(s, d)); });
    // Projection of an exp profile at 14 bands: the residual above band 2*14 is below 1e-10.
    for (int i = 0; i < num_coeffs(order); ++i) EXPECT_NEAR(rotated[i], direct[i], 1e-9) << i;
  }
}

TEST(Irradiance, ConstantLightGivesPi) {
  // Constant radiance 1: irradiance pi for every normal; H(N) . 1 = 1.
  const int order = 4;
  std::vector<double> light(16, 0.0), lt(16), h(16);
  light[0] = kSqrt4Pi;
  irradiance_env(order, light.data(), lt.data());
  std::mt19937 rng(4);
  for (int t = 0; t < 10; ++t) {
    auto nrm = random_dir(rng);
    EXPECT_NEAR(reconstruct(order, lt.data(), nrm), kPi, kClosedFormTol);
    irradiance_weight(order, nrm, h.data());
    double dotp = 0;
    for (int i = 0; i < 16; ++i) dotp += h[i] * light[i];
    EXPECT_NEAR(dotp, 1.0, kClosedFormTol);
  }
}

TEST(Irradiance, DirectionalLobeMatchesBruteForce) {
  // L(s) = max(0, s.d)^4: L~(N) = int L(s) max(0, s.N) ds by fine quadrature, against the
  // order-n convolution; agreement limited by the truncation of L to order n... so compare the
  // convolution of the order-8 projection with brute force using the same order-8 projection.
  const int order = 8;
  SphereQuadrature q = make_sphere_quadrature(40);
  Vec3<double> d = normalize(Vec3<double>{0.3, -0.5, 0.8});
  auto light = project(order, q, [&](const Vec3<double>& s) { return std::pow(std::max(0.0, dot(s, d)), 4); });
  std::vector<double> lt(64);
  irradiance_env(order, light.data(), lt.data());
  std::mt19937 rng(5);
  for (int t = 0; t < 5; ++t) {
    auto nrm = random_dir(rng);
    double brute = 0;
    for (std::size_t k = 0; k < q.dirs.size(); ++k)
      brute += q.weights[k] * reconstruct(order, light.data(), q.dirs[k]) * std::max(0.0, dot(q.dirs[k], nrm));
    // the clamped cosine's kink limits the 40-band quadrature to ~1e-5
    EXPECT_NEAR(reconstruct(order, lt.data(), nrm), brute, 1e-4);
  }
}

TEST(Windowing, CosineFilter) {
  EXPECT_DOUBLE_EQ(window_factor(0, 8), 1.0);
  EXPECT_NEAR(window_factor(4, 8), std::cos(kPi / 4), kClosedFormTol);
  EXPECT_EQ(window_factor(8, 8), 0.0);
  EXPECT_THROW(window_factor(1, 0.0), std::invalid_argument);
  std::vector<double> f(16, 1.0);
  apply_window(4, f.data(), 8.0);
  EXPECT_NEAR(f[index(3, -2)], std::cos(kPi / 2 * 3 / 8.0), kClosedFormTol);
}

TEST(Projection, LatLongRoundTrip) {
  // A map sampled from a known order-3 function projects back to its coefficients; the error is
  // that of the bilinear reconstruction of the samples, O(1/H^2) on a 512x256 map.
  const int order = 3, w = 512, h = 256;
  std::vector<double> coef = {1.0, 0.3, -0.2, 0.5, 0.1, -0.4, 0.25, 0.05, -0.15};
  std::vector<float> img(static_cast<std::size_t>(w) * h * 2);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double val = reconstruct(order, coef.data(), latlong_direction(u, v, w, h));
      img[(v * w + u) * 2] = float(val);
      img[(v * w + u) * 2 + 1] = float(2 * val);
    }
  auto proj = project_latlong(order, img.data(), w, h, 2);
  for (int i = 0; i < 9; ++i) {
    EXPECT_NEAR(proj[i], coef[i], 1e-4) << i;
    EXPECT_NEAR(proj[9 + i], 2 * coef[i], 2e-4) << i;
  }
  img[17] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(project_latlong(order, img.data(), w, h, 2), std::invalid_argument);
  EXPECT_THROW(project_latlong(order, img.data(), 0, h, 2), std::invalid_argument);
}

TEST(Validation, BadOrdersAndValuesAreNamed) {
  EXPECT_THROW(check_order(0, "x"), std::invalid_argument);
  EXPECT_THROW(check_order(9, "x"), std::invalid_argument);
  std::vector<double> v = {1.0, std::nan("")};
  try {
    check_finite(std::span<const double>(v), "test vector");
    FAIL() << "NaN accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("coefficient 1"), std::string::npos) << e.what();
  }
}
