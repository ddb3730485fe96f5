// Precomputed tables: cap ZH closed forms against brute force, interpolation error that shrinks
// with resolution as linear interpolation must (O(h^2)), OL coefficients and lookups.
#include <gtest/gtest.h>
#include <algorithm>
#include <random>

#include <cmath>

#include "softgi/sh/exp_log.hpp"
#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/tables.hpp"

using namespace softgi::sh;

namespace {
// Cap ZH against a brute-force quadrature of the discontinuous indicator: a graded 1D
// Gauss-Legendre in mu split at the cap edge is exact up to rounding.
constexpr double kCapBruteTol = 1e-12;
}  // namespace

TEST(CapTables, VisibilityMatchesBruteForce) {
  for (int order : {2, 4, 8}) {
    for (double deg : {0.0, 1e-5, 1.0, 17.0, 45.0, 80.0, 90.0}) {
      double th = deg * kPi / 180, c = std::cos(th);
      auto zh = cap_visibility_zh(order, th);
      for (int l = 0; l < order; ++l) {
        // g_l = 2 pi int_{-1}^{c} y_l0(mu) dmu (visible outside the cap)
        double kl = std::sqrt((2 * l + 1) / (4 * kPi));
        auto pl = [&](double mu) {
          double p0 = 1, p1 = mu;
          if (l == 0) return 1.0;
          for (int k = 2; k <= l; ++k) {
            double p2 = ((2 * k - 1) * mu * p1 - (k - 1) * p0) / k;
            p0 = p1;
            p1 = p2;
          }
          return p1;
        };
        double brute = 2 * kPi * kl * integrate(pl, -1.0, c, 16);
        EXPECT_NEAR(zh[l], brute, kCapBruteTol) << order << " " << deg << " " << l;
      }
    }
  }
  auto full = cap_visibility_zh(4, 0.0);
  EXPECT_NEAR(full[0], kSqrt4Pi, 1e-15);
  auto half = cap_visibility_zh(4, kPi / 2);
  EXPECT_NEAR(half[0], kSqrt4Pi / 2, 1e-14);  // half the sphere visible
  EXPECT_THROW(cap_visibility_zh(4, -0.1), std::invalid_argument);
  EXPECT_THROW(cap_visibility_zh(4, std::nan("")), std::invalid_argument);
}

TEST(CapTables, LogOfTinyCapIsNearlyLinear) {
  // For a tiny cap g = 1 - c with c small: log(g) ~ -c (first order), so the log ZH approaches
  // the visibility's deviation from 1.
  auto g = cap_visibility_zh(4, 0.01);
  auto f = cap_log_zh(4, 0.01);
  EXPECT_NEAR(f[0], g[0] - kSqrt4Pi, 1e-6);
  for (int l = 1; l < 4; ++l) EXPECT_NEAR(f[l], g[l], 1e-6);
}

TEST(ShTablesTest, InterpolationErrorShrinksQuadratically) {
  TableOptions a{4, 64, TableParam::Theta, 0.02, true};
  TableOptions b = a;
  b.resolution = 127;  // half the spacing
  ShTables ta(a), tb(b);
  // Linear interpolation error ~ h^2 f''/8: halving h divides it by ~4 (3..5 allows for where the
  // maximum sits).
  double ra = ta.cap_visibility().max_interp_error / tb.cap_visibility().max_interp_error;
  EXPECT_GT(ra, 3.0);
  EXPECT_LT(ra, 5.0);
  double rd = ta.D_averaged().max_interp_error / tb.D_averaged().max_interp_error;
  EXPECT_GT(rd, 3.0);
  EXPECT_LT(rd, 5.0);
  EXPECT_GT(ta.cap_log().max_interp_error, 0.0);
  EXPECT_GT(ta.sl_weight().max_interp_error, 0.0);
}

TEST(ShTablesTest, LookupMatchesDirectEvaluation) {
  ShTables t(TableOptions{4, 256, TableParam::Alpha, 0.02, false});
  double out[4];
  for (double alpha : {0.0, 0.25, 0.7, 1.0}) {
    t.D_averaged().lookup(alpha, out);
    auto d = indirect_D_quadrature(4, alpha);
    // on a sample (0, 1) or between samples: interpolation error of a smooth function at 1/255 spacing
    for (int l = 0; l < 4; ++l) EXPECT_NEAR(out[l], d[l], 1e-4) << alpha;
  }
  // Out-of-range parameters clamp to the ends; NaN maps to the first row instead of propagating.
  t.cap_visibility().lookup(2.0, out);
  EXPECT_NEAR(out[0], cap_visibility_zh(4, kPi / 2)[0], 1e-12);
  t.cap_visibility().lookup(std::nan(""), out);
  EXPECT_TRUE(std::isfinite(out[0]));
}

// ol_lookup's bucketed search against the definition: linear interpolation over the increasing prefix
// of the sweep, its cell found by a search of the whole prefix. Exact equality: the same cell gives
// the same arithmetic. Norms drawn at random over the range, on every sample, and one ulp either side.
TEST(ShTablesTest, OlLookupFindsTheCellOfTheWholeSweep) {
  for (int order : {3, 4, 6}) {
    ShTables t(TableOptions{order, 256, TableParam::Theta, 0.02, false});
    std::vector<double> xs, as, bs;
    for (std::size_t k = 0; k < t.ol_norm().size(); ++k) {
      if (!xs.empty() && !(t.ol_norm()[k] > xs.back())) break;
      xs.push_back(t.ol_norm()[k]);
      as.push_back(t.ol_a()[k]);
      bs.push_back(t.ol_b()[k]);
    }
    ASSERT_GE(xs.size(), 2u);
    std::vector<double> norms;
    std::mt19937 rng(7u + order);
    std::uniform_real_distribution<double> u(xs.front(), xs.back());
    for (int i = 0; i < 20000; ++i) norms.push_back(u(rng));
    for (double x : xs)
      for (double v : {x, std::nextafter(x, 0.0), std::nextafter(x, 1e9)}) norms.push_back(v);
    int checked = 0;
    for (double norm : norms) {
      if (!(norm > xs.front()) || norm >= xs.back()) continue;
      const std::size_t k = static_cast<std::size_t>(std::upper_bound(xs.begin(), xs.end(), norm) - xs.begin()) - 1;
      const double w = (norm - xs[k]) / (xs[k + 1] - xs[k]);
      double a = 0.0, b = 0.0;
      t.ol_lookup(norm, a, b);
      ASSERT_EQ(a, as[k] + w * (as[k + 1] - as[k])) << "order " << order << ", norm " << norm;
      ASSERT_EQ(b, bs[k] + w * (bs[k + 1] - bs[k])) << "order " << order << ", norm " << norm;
      ++checked;
    }
    EXPECT_GT(checked, 20000);
  }
}

TEST(ShTablesTest, OptimalLinearCoefficients) {
  ShTables t(TableOptions{4, 256, TableParam::Theta, 0.02, false});
  // theta -> 0: exp(f) ~ 1 + f, so a -> 1 and b -> 1 (eq. 24 limit).
  EXPECT_NEAR(t.ol_a().front(), 1.0, 1e-12);
  EXPECT_NEAR(t.ol_b().front(), 1.0, 1e-12);
  // Paper 004 Figure 3: at order 4 the cap curves are usable up to ||f^|| ~ 4.8 (about 50 degrees);
  // our sweep is monotone in ||f^|| at least that far.
  EXPECT_GT(t.ol_max_norm(), 4.8);
  double a, b;
  t.ol_lookup(0.0, a, b);
  EXPECT_NEAR(a, 1.0, 1e-12);
  t.ol_lookup(1e9, a, b);
  EXPECT_TRUE(std::isfinite(a) && std::isfinite(b));
  // eq. 24 by hand at one sample: least-squares projection of g^ onto (1, f^).
  int k = 100;
  double th = t.cap_visibility().x[k];
  auto g = cap_visibility_zh(4, th);
  auto f = cap_log_zh(4, th);
  double s = std::exp(-f[0] / kSqrt4Pi), ff = 0, gf = 0;
  for (int l = 1; l < 4; ++l) {
    ff += f[l] * f[l];
    gf += s * g[l] * f[l];
  }
  EXPECT_NEAR(t.ol_a()[k], s * g[0] / kSqrt4Pi, 1e-12);
  EXPECT_NEAR(t.ol_b()[k], gf / ff, 1e-12);
  EXPECT_NEAR(t.ol_norm()[k], std::sqrt(ff), 1e-12);
}

TEST(ShTablesTest, RejectsBadOptions) {
  EXPECT_THROW(ShTables(TableOptions{9, 256, TableParam::Theta, 0.02, false}), std::invalid_argument);
  EXPECT_THROW(ShTables(TableOptions{4, 1, TableParam::Theta, 0.02, false}), std::invalid_argument);
  EXPECT_THROW(ShTables(TableOptions{4, 256, TableParam::Theta, 0.0, false}), std::invalid_argument);
  EXPECT_THROW(ShTables(TableOptions{4, 256, TableParam::Theta, std::nan(""), false}), std::invalid_argument);
}

TEST(ShTablesTest, ExactIndirectOperatorTableOnlyWhenAsked) {
  ShTables plain(TableOptions{3, 64, TableParam::Alpha, 0.02, false});
  EXPECT_EQ(plain.M_exact().rows(), 0);
  ShTables t(TableOptions{3, 64, TableParam::Theta, 0.02, true, true});
  ASSERT_EQ(t.M_exact().width, 81);
  std::vector<double> out(81);
  t.M_exact().lookup(t.M_exact().x[10], out.data());  // on a sample: exact
  auto m = indirect_M(3, std::sin(t.M_exact().x[10]));
  for (int i = 0; i < 81; ++i) EXPECT_NEAR(out[i], m[i], 1e-14);
  // Uniform in theta, M is smooth: measured 3.5e-4 at 64 samples (largest near 90 degrees).
  EXPECT_GT(t.M_exact().max_interp_error, 0.0);
  EXPECT_LT(t.M_exact().max_interp_error, 1e-3);
  // Uniform in alpha it is not: cos(theta) = sqrt(1 - alpha^2) has an infinite slope at alpha = 1, so
  // the error there is two orders larger (measured 0.047) and shrinks only like sqrt(h). docs/sh.md
  // recommends theta sampling; alpha stays selectable because paper 000 tabulates against alpha.
  ShTables a(TableOptions{3, 64, TableParam::Alpha, 0.02, true, true});
  EXPECT_GT(a.M_exact().max_interp_error, 10 * t.M_exact().max_interp_error);
  EXPECT_GT(a.M_exact().max_interp_error_at, 0.95);
}
