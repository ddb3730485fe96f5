// Spherical lights, paper 001 section 6.1: cos gamma (eq. 17) against the explicit geometry, the ZH
// weight table (eq. 16 normalised) against brute-force integration over the light's sphere, its limits,
// and the rotated dot product (eq. 18).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "../../techniques/spherical_lights/sl_tables.hpp"
#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

using namespace softgi;
using namespace softgi::techniques::spherical_lights;

namespace {

constexpr double kHalfPi = 0.5 * sh::kPi;

glm::dvec3 random_unit(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), ph(0.0, 2.0 * sh::kPi);
  const double z = u(rng), p = ph(rng), r = std::sqrt(1.0 - z * z);
  return {r * std::cos(p), r * std::sin(p), z};
}

// Any unit vector orthogonal to a.
glm::dvec3 orthogonal(const glm::dvec3& a) {
  const glm::dvec3 h = std::abs(a.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  return glm::normalize(glm::cross(a, h));
}

// cos gamma from explicit points: centre c, radius r, surface point x, receiver p (clamped at 0).
double geometric_cos_gamma(const glm::dvec3& c, double r, const glm::dvec3& x, const glm::dvec3& p) {
  const glm::dvec3 n = (x - c) / r;
  return std::max(0.0, glm::dot(n, glm::normalize(p - x)));
}

double y_l0(int order, int l, double mu) {
  std::array<double, sh::kMaxCoeffs> y{};
  sh::eval_basis(order, sh::Vec3<double>{std::sqrt(std::max(0.0, 1.0 - mu * mu)), 0.0, mu}, y.data());
  return y[sh::index(l, 0)];
}

// Rotated exact weight (double) dotted with L: eq. 18 without the table.
double exact_average(int order, const std::vector<double>& L, const glm::dvec3& dir, double theta) {
  const std::vector<double> w = weight_zh(order, theta);
  std::vector<double> f(order * order);
  sh::zh_rotate(order, w.data(), sh::Vec3<double>{dir.x, dir.y, dir.z}, f.data());
  double s = 0.0;
  for (int i = 0; i < order * order; ++i) s += f[i] * L[i];
  return s;
}

}  // namespace

TEST(SlWeight, CosGammaMatchesExplicitGeometry) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> th(0.0, kHalfPi), al(0.0, sh::kPi), rad(0.1, 3.0);
  for (int i = 0; i < 2000; ++i) {
    const double theta = th(rng), alpha = al(rng), r = rad(rng);
    const glm::dvec3 c = 5.0 * random_unit(rng), axis = random_unit(rng), side = orthogonal(axis);
    const glm::dvec3 p = c + axis * (r / std::sin(theta));
    const glm::dvec3 x = c + r * (std::cos(alpha) * axis + std::sin(alpha) * side);
    // Both in double; the geometric side subtracts points ~r/sin(theta) apart: 1e-9 covers its rounding.
    EXPECT_NEAR(cos_gamma(theta, alpha), geometric_cos_gamma(c, r, x, p), 1e-9) << theta << " " << alpha;
  }
  // Eq. 17 as printed (atan form), where it is defined (0 < alpha, theta).
  for (int i = 0; i < 500; ++i) {
    const double theta = th(rng), alpha = al(rng);
    if (theta < 1e-6 || alpha < 1e-6) continue;
    const double s = std::sin(theta);
    const double paper = std::max(0.0, std::sin(std::atan((1.0 - s * std::cos(alpha)) / (s * std::sin(alpha))) - alpha));
    EXPECT_NEAR(cos_gamma(theta, alpha), paper, 1e-12);
  }
  EXPECT_DOUBLE_EQ(cos_gamma(0.3, 0.0), 1.0);                 // facing point, alpha = 0
  EXPECT_DOUBLE_EQ(cos_gamma(0.0, 0.7), std::cos(0.7));       // theta = 0: receiver at infinity
  EXPECT_DOUBLE_EQ(cos_gamma(0.0, 2.0), 0.0);
  EXPECT_DOUBLE_EQ(cos_gamma(kHalfPi, 0.0), 0.0);             // receiver on the sphere
  EXPECT_DOUBLE_EQ(cos_gamma(0.5, std::acos(std::sin(0.5)) + 1e-9), 0.0);  // just past the terminator
}

TEST(SlWeight, ZhMatchesOneDimensionalQuadratureOfCosGamma) {
  // weight_zh integrates exactly in a substituted variable; here the plain alpha integral of eq. 17,
  // graded Gauss-Legendre panels: both to ~1e-12, compared at 1e-9.
  const int order = 8;
  for (double theta : {1e-4, 0.05, 0.4, 0.9, 1.3, 1.55, 1.5707}) {
    const double amax = std::acos(std::sin(theta));
    auto integral = [&](int l) {
      return sh::integrate([&](double a) { return cos_gamma(theta, a) * (l < 0 ? 1.0 : y_l0(order, l, std::cos(a))) * std::sin(a); },
                           0.0, amax, 24, amax * 1e-3);
    };
    const double den = integral(-1);
    const std::vector<double> w = weight_zh(order, theta);
    for (int l = 0; l < order; ++l) EXPECT_NEAR(w[l], integral(l) / den, 1e-9) << "theta " << theta << " l " << l;
  }
}

TEST(SlWeight, TableMatchesBruteForceSphereIntegral) {
  const int order = 4;
  const WeightTable table = make_weight_table(order, 256);
  // Product rule on the light's sphere, 600 x 1200 nodes. The integrand of eq. 16 has a kink at the
  // terminator (cos gamma -> 0 linearly) that is not aligned with the grid: error O(h^2) with
  // h = pi/600, at most ~3e-5 of the integrand's scale (|L| <= 4 here); the kink errors largely cancel,
  // measured 1.5e-7. Tolerance 5e-6 for the exact weight.
  const sh::SphereQuadrature q = sh::make_sphere_quadrature(600);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0), dist(1.05, 8.0), rad(0.2, 2.0);
  std::array<double, sh::kMaxCoeffs> y{};
  double worst_exact = 0.0, worst_table = 0.0;
  for (int trial = 0; trial < 12; ++trial) {
    std::vector<double> L(order * order);
    std::vector<float> Lf(order * order);
    for (int i = 0; i < order * order; ++i) Lf[i] = static_cast<float>(L[i] = u(rng));
    const double r = rad(rng);
    const glm::dvec3 c(u(rng), u(rng), u(rng));
    const glm::dvec3 dir = random_unit(rng);
    const glm::dvec3 p = c + dir * (r * dist(rng));
    const double theta = std::asin(r / glm::length(p - c));
    double num = 0.0, den = 0.0;
    for (std::size_t k = 0; k < q.dirs.size(); ++k) {
      const glm::dvec3 w(q.dirs[k].x, q.dirs[k].y, q.dirs[k].z);
      const double g = geometric_cos_gamma(c, r, c + r * w, p);
      if (g <= 0.0) continue;
      sh::eval_basis(order, q.dirs[k], y.data());
      double Lw = 0.0;
      for (int i = 0; i < order * order; ++i) Lw += L[i] * y[i];
      num += q.weights[k] * g * Lw;
      den += q.weights[k] * g;
    }
    const double brute = num / den;
    const double exact = exact_average(order, L, dir, theta);
    const float tab = average_radiance(table, Lf.data(), glm::vec3(dir), static_cast<float>(theta));
    worst_exact = std::max(worst_exact, std::abs(exact - brute));
    worst_table = std::max(worst_table, std::abs(tab - brute));
    // The table adds linear interpolation over pi/510-wide rows (h^2 |w''|/8 ~ 1e-5 per band, times
    // 16 coefficients of size <= 1) and float rounding: 5e-5 (measured 3.7e-6).
    EXPECT_NEAR(exact, brute, 5e-6) << "trial " << trial << " theta " << theta;
    EXPECT_NEAR(tab, brute, 5e-5) << "trial " << trial << " theta " << theta;
  }
  std::printf("worst |exact - brute| %.3g, |table - brute| %.3g\n", worst_exact, worst_table);
}

TEST(SlWeight, LimitsThetaZeroAndHalfPi) {
  const int order = 8;
  const std::vector<double> cc = sh::clamped_cosine_zh(order);
  const std::vector<double> w0 = weight_zh(order, 0.0), w_small = weight_zh(order, 1e-7);
  for (int l = 0; l < order; ++l) {
    EXPECT_NEAR(w0[l], cc[l] / sh::kPi, 1e-15);
    // w_l(theta) - w_l(0) = O(sin theta): 1e-7 within 1e-6.
    EXPECT_NEAR(w_small[l], cc[l] / sh::kPi, 1e-6) << l;
  }
  const WeightTable t = make_weight_table(order, 64);
  std::vector<float> out(order);
  t.lookup(0.0f, out.data());
  for (int l = 0; l < order; ++l) EXPECT_NEAR(out[l], cc[l] / sh::kPi, 1e-7);
  // theta -> pi/2: support alpha <= pi/2 - theta, w_l -> y_l0(+z) with error O(l^2 alpha^2).
  const std::vector<double> w_top = weight_zh(order, kHalfPi), w_near = weight_zh(order, kHalfPi - 1e-4);
  t.lookup(static_cast<float>(kHalfPi) + 0.1f, out.data());  // clamped
  for (int l = 0; l < order; ++l) {
    const double delta = std::sqrt((2.0 * l + 1.0) / (4.0 * sh::kPi));
    EXPECT_NEAR(w_top[l], delta, 1e-15);
    EXPECT_NEAR(w_near[l], delta, 1e-6) << l;
    EXPECT_NEAR(out[l], delta, 1e-6);
  }
  // The normalisation: w_0 = y_00 at every theta.
  for (double th : {0.0, 0.1, 0.7, 1.2, 1.57})
    EXPECT_NEAR(weight_zh(order, th)[0], 1.0 / std::sqrt(4.0 * sh::kPi), 1e-14);
  // The weight narrows monotonically: w_1 / (y_10(+z)) = mean cos alpha grows with theta.
  double prev = 0.0;
  for (int k = 0; k < 64; ++k) {
    EXPECT_GE(t.w[k * order + 1], prev - 1e-7f);
    prev = t.w[k * order + 1];
  }
}

TEST(SlWeight, ConstantIntensityGivesItsMean) {
  const int order = 5;
  const WeightTable t = make_weight_table(order, 128);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> th(0.0, kHalfPi);
  std::vector<float> L(order * order, 0.0f);
  L[0] = 2.5f;
  for (int i = 0; i < 200; ++i) {
    const glm::vec3 d(random_unit(rng));
    // Float rounding of a handful of products: 1e-6 relative.
    EXPECT_NEAR(average_radiance(t, L.data(), d, static_cast<float>(th(rng))), 2.5 / std::sqrt(4.0 * sh::kPi), 1e-6);
  }
}

TEST(SlWeight, RejectsBadArguments) {
  EXPECT_THROW(make_weight_table(0, 16), std::invalid_argument);
  EXPECT_THROW(make_weight_table(4, 1), std::invalid_argument);
  EXPECT_THROW(weight_zh(4, -0.1), std::invalid_argument);
  EXPECT_THROW(weight_zh(4, std::nan("")), std::invalid_argument);
}
