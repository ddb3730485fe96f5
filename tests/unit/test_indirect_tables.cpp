// Tests of the indirect operators of paper 000 (D, eq. 14; M, eq. 16) and the spherical-light weight
// of paper 001 (eqs. 16-18), core/src/sh/indirect_tables.cpp. Every reference is computed along an
// independent path: brute-force 2D quadrature over the proxy's *surface* (not over ray directions)
// with eval_basis(), the closed form, analytic limits, or 40-digit mpmath values in the original
// variable mu (see docs/sh_indirect_tables.md for the script).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::sh {
namespace {

const std::vector<double> kAlphas = {0.0, 1e-7, 1e-3, 0.1, 0.5, 0.9, 0.999, 1.0 - 1e-7, 1.0};

double cos_of(double s) { return std::sqrt((1.0 - s) * (1.0 + s)); }

// y_l0(z) = sqrt((2l+1)/(4pi)) P_l(z), from eval_basis (the project's basis, not the code under test).
double y_l0(int l, double z) {
  std::array<double, kMaxCoeffs> y{};
  double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
  eval_basis(l + 1, Vec3<double>{rho, 0.0, z}, y.data());
  return y[index(l, 0)];
}

// Legendre polynomial P_l(z) (for the analytic cap projections).
double legendre(int l, double z) {
  double p0 = 1.0, p1 = z;
  if (l == 0) return p0;
  for (int k = 2; k <= l; ++k) {
    double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

// int_C^1 y_l0(mu) dmu in closed form: (P_{l-1}(C) - P_{l+1}(C)) / (2l+1) for l >= 1, 1 - C for l = 0.
double cap_zonal_integral(int l, double C) {
  double k = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi));
  if (l == 0) return k * (1.0 - C);
  return k * (legendre(l - 1, C) - legendre(l + 1, C)) / (2.0 * l + 1.0);
}

// Composite Gauss-Legendre on [a, b], panels graded geometrically towards a from width h0 (ratio 2).
struct TestRule {
  std::vector<double> x, w;
};
TestRule graded(double a, double b, double h0, int n) {
  const GaussLegendre& gl = gauss_legendre(n);
  TestRule r;
  double lo = a, width = std::min(h0, b - a);
  while (lo < b) {
    double hi = std::min(b, lo + width);
    for (int i = 0; i < n; ++i) {
      r.x.push_back(0.5 * (lo + hi) + 0.5 * (hi - lo) * gl.nodes[i]);
      r.w.push_back(0.5 * (hi - lo) * gl.weights[i]);
    }
    lo = hi;
    width *= 2.0;
  }
  return r;
}

// Brute-force 2D reference for the canonical proxy (paper 000 section 5): centre c = (0,0,1), radius
// S, receiver p at the origin. Instead of ray directions it walks the sphere's visible surface: the
// unit normal n = (rho cos phi, rho sin phi, -zp) with zp in [S, 1]; the point q = c + S n, the ray
// direction s = q / |q|, and the solid angle element ds = S^2 (zp - S) / |q|^3 dzp dphi with
// |q|^2 = 1 - 2 S zp + S^2. Calls visit(s, n, ds) for every node. The 1/|q|^3 peak at zp = 1 (width
// ~(1-S)^2) is resolved by grading towards it; phi uses enough uniform samples to integrate every
// trigonometric polynomial of the degree a product of two order-8 SH has.
template <class F>
void for_each_proxy_surface_node(double S, F&& visit) {
  const double eps = 1.0 - S;
  TestRule r = graded(0.0, eps, std::max(1e-12, std::min(eps / 8.0, eps * eps / (2.0 * S))), 24);
  const int nphi = 40;
  for (std::size_t k = 0; k < r.x.size(); ++k) {
    // In t = 1 - zp, written without cancellation (near S = 1, |q| ~ 1 - S is a small difference):
    // |q|^2 = (1 - S)^2 + 2 S t, q_z = 1 - S zp = (1 - S) + S t, zp - S = (1 - S) - t.
    double t = r.x[k], zp = 1.0 - t;
    double rho = std::sqrt(t * (2.0 - t));
    double q2 = eps * eps + 2.0 * S * t;
    double ds = r.w[k] * (2.0 * kPi / nphi) * S * S * (eps - t) / (q2 * std::sqrt(q2));
    for (int j = 0; j < nphi; ++j) {
      double phi = 2.0 * kPi * (j + 0.25) / nphi;
      Vec3<double> n{rho * std::cos(phi), rho * std::sin(phi), -zp};
      Vec3<double> s = normalize(Vec3<double>{S * n.x, S * n.y, eps + S * t});
      visit(s, n, ds);
    }
  }
}

// 40-digit references (mpmath, mp.dps = 40, tanh-sinh quadrature in the ORIGINAL variable mu = s_z:
// D_l = 1/(1-C) int_C^1 y_l0((mu^2 - mu sqrt(mu^2 - C^2) - 1)/S) dmu and
// w_l = int_S^1 g y_l0 dmu / int_S^1 g dmu, g = (mu - S)/sqrt(1 - 2 S mu + S^2)); bands 0..7.
struct Ref {
  double alpha;
  std::array<double, 8> v;
};
const std::array<Ref, 4> kDRef = {{
    {0.001, {0.28209479177387814347, -0.3259792277778175136, 0.15820052727636405907, -0.00037381601663902150251,
             -0.035261165021417304777, 0.00014618675464173190526, 0.015891883395888488241,
             -0.000095596967967973484343}},
    {0.5, {0.28209479177387814347, -0.42898886799980083678, 0.4241209502450465308, -0.33042554320659132084,
           0.20708344161250373779, -0.10294814314448487154, 0.041292796321535882286, -0.018439038574179622881}},
    {0.999, {0.28209479177387814347, -0.48859538580926801228, 0.6307555342040631595, -0.74628737085015083401,
             0.84616100692692745756, -0.93539805076339030646, 1.0167960508752350584, -1.0921029076445739676}},
    {1.0 - 1e-7, {0.28209479177387814347, -0.48860251189563789352, 0.63078313047683683891, -0.74635266511348989482,
                  0.84628437519550601012, -0.93560257941822845398, 1.0171072359637210918,
                  -1.0925484301361520584}},
}};
const std::array<Ref, 4> kWRef = {{
    {0.001, {0.28209479177387814347, 0.32592499650049544911, 0.15807440227650722187, 0.00024924401099316888844,
             -0.035308508129568633141, -0.0001268646019487187241, 0.015913167694626689296,
             0.000088887201619474552243}},
    {0.5, {0.28209479177387814347, 0.41491922199566874163, 0.37920092922039600675, 0.25161553173080209024,
           0.10914292371839210599, 0.010492695201832357561, -0.024948009355065578659, -0.014909502488198033609}},
    {0.999, {0.28209479177387814347, 0.48850159648000451331, 0.63039237055641284705, 0.7454282557491825378,
             0.84453815471226723302, 0.93270835209489501338, 1.0127051685364431712, 1.0862483866971705424}},
    {1.0 - 1e-7, {0.28209479177387814347, 0.48860250212759289815, 0.63078309264536205784, 0.74635257558788352673,
                  0.84628420600802010517, 0.93560229885253850512, 1.0171068089538625199,
                  1.0925478185599757753}},
}};

// Quadrature vs. an exact value: 32-node graded Gauss reaches ~1e-15; 1e-12 leaves room for the
// rounding of the recurrences at l = 7 and still catches any wrong term or Jacobian.
constexpr double kExactTol = 1e-12;

// ---------------------------------------------------------------------------------------------
// D(theta)

TEST(IndirectTables, DQuadratureMatchesStableClosedForm) {
  for (double a : kAlphas) {
    auto q = indirect_D_quadrature(3, a);
    auto c = indirect_D_closed_form(a);
    for (int l = 0; l < 3; ++l) EXPECT_NEAR(q[l], c[l], kExactTol) << "alpha " << a << " l " << l;
    for (int l = 0; l < 3; ++l) EXPECT_TRUE(std::isfinite(c[l]));
  }
}

TEST(IndirectTables, DQuadratureMatchesMpmathAllBands) {
  for (const Ref& r : kDRef) {
    auto q = indirect_D_quadrature(8, r.alpha);
    for (int l = 0; l < 8; ++l) EXPECT_NEAR(q[l], r.v[l], kExactTol) << "alpha " << r.alpha << " l " << l;
  }
}

TEST(IndirectTables, DLimits) {
  // alpha = 0 (point proxy): rays hit the near hemisphere uniformly in projected area, so
  // D_l = 2 int_0^1 x y_l0(-x) dx; alpha = 1 (proxy touching p): every ray hits p, D_l = y_l0(-z).
  // Reference for alpha = 0 by Gauss-Legendre, exact for these polynomials.
  const GaussLegendre& gl = gauss_legendre(16);
  for (int order = 2; order <= kMaxOrder; ++order) {
    auto d0 = indirect_D_quadrature(order, 0.0);
    auto d1 = indirect_D_quadrature(order, 1.0);
    for (int l = 0; l < order; ++l) {
      double ref0 = 0.0;
      for (int i = 0; i < 16; ++i) {
        double x = 0.5 + 0.5 * gl.nodes[i];
        ref0 += 0.5 * gl.weights[i] * 2.0 * x * y_l0(l, -x);
      }
      EXPECT_NEAR(d0[l], ref0, kExactTol) << "order " << order << " l " << l;
      EXPECT_NEAR(d1[l], y_l0(l, -1.0), kExactTol) << "order " << order << " l " << l;
    }
  }
  // Closed-form limits of D at alpha = 0 (paper 000 section 5).
  EXPECT_NEAR(indirect_D_quadrature(3, 0.0)[0], 1.0 / (2.0 * std::sqrt(kPi)), kExactTol);
  EXPECT_NEAR(indirect_D_quadrature(3, 0.0)[1], -2.0 / 3.0 * std::sqrt(3.0 / (4.0 * kPi)), kExactTol);
  // Continuity: D is smooth in alpha at 0 (|dD/dalpha| < 1), so alpha = 1e-7 is within 1e-6 of the limit.
  constexpr double kNearZeroTol = 1e-6;
  auto a = indirect_D_quadrature(8, 0.0), b = indirect_D_quadrature(8, 1e-7);
  for (int l = 0; l < 8; ++l) EXPECT_NEAR(a[l], b[l], kNearZeroTol);
  // Near alpha = 1, D moves with cos theta ~ sqrt(2 (1 - alpha)) = 4.5e-4 at 1 - 1e-7; |dD/dC| < 10.
  constexpr double kNearOneTol = 5e-3;
  a = indirect_D_quadrature(8, 1.0);
  b = indirect_D_quadrature(8, 1.0 - 1e-7);
  for (int l = 0; l < 8; ++l) EXPECT_NEAR(a[l], b[l], kNearOneTol);
}

TEST(IndirectTables, DMatchesBruteForce2D) {
  // The brute-force surface quadrature agrees with the implementation to <= 5e-15 (measured) at these
  // alphas; 1e-12 leaves margin for other compilers and is far below any formula error (a wrong
  // Jacobian or normal changes D at the 1e-2 level).
  constexpr double kBruteTol = 1e-12;
  for (double a : {0.1, 0.5, 0.9, 0.999}) {
    std::array<double, kMaxOrder> ref{};
    double omega = 0.0;
    std::array<double, kMaxCoeffs> y{};
    for_each_proxy_surface_node(a, [&](const Vec3<double>&, const Vec3<double>& n, double ds) {
      eval_basis(kMaxOrder, n, y.data());
      omega += ds;
      for (int l = 0; l < kMaxOrder; ++l) ref[l] += ds * y[index(l, 0)];
    });
    EXPECT_NEAR(omega, 2.0 * kPi * (1.0 - cos_of(a)), kBruteTol);
    for (int order = 2; order <= kMaxOrder; ++order) {
      auto d = indirect_D_quadrature(order, a);
      ASSERT_EQ(static_cast<int>(d.size()), order);
      for (int l = 0; l < order; ++l) EXPECT_NEAR(d[l], ref[l] / omega, kBruteTol) << "alpha " << a << " l " << l;
    }
  }
}

TEST(IndirectTables, PrintedClosedFormIsCorrectInDouble) {
  // The printed order-3 form (paper 000 section 5) is algebraically right: in double it matches the
  // quadrature away from alpha -> 0. Its cancellation grows like d^3 ulps (d = 1/alpha); measured
  // 7e-13 at alpha = 0.1, so 1e-11 is the tolerance for alpha >= 0.1.
  constexpr double kPrintedDoubleTol = 1e-11;
  for (double a : {0.1, 0.5, 0.9, 0.999, 1.0 - 1e-7, 1.0}) {
    auto p = indirect_D_closed_form_as_printed<double>(a);
    auto q = indirect_D_quadrature(3, a);
    for (int l = 0; l < 3; ++l) EXPECT_NEAR(p[l], q[l], kPrintedDoubleTol) << "alpha " << a << " l " << l;
  }
}

TEST(IndirectTables, PrintedClosedFormCancelsInFloat) {
  // The point of the rewrite: evaluated literally in float, the printed form is fine at moderate alpha
  // (a few float ulps of |D| ~ 0.5) but breaks down as alpha -> 0, where the stable form is exact.
  constexpr double kFloatModerateTol = 2e-5;  // ~100 ulps of 0.5 in float: the cancellation at alpha=0.5 is mild
  for (double a : {0.5, 0.9, 1.0}) {
    auto p = indirect_D_closed_form_as_printed<float>(static_cast<float>(a));
    auto c = indirect_D_closed_form(static_cast<float>(a));
    for (int l = 0; l < 3; ++l) EXPECT_NEAR(p[l], c[l], kFloatModerateTol) << "alpha " << a;
  }
  // At alpha = 1e-3 the float result is off by more than 1% of |D| (measured: 8 in D1, 3e4 in D2) ...
  constexpr double kFloatBrokenMin = 1e-2;
  {
    auto p = indirect_D_closed_form_as_printed<float>(1e-3f);
    auto c = indirect_D_closed_form(static_cast<double>(1e-3f));
    double err = std::max(std::abs(p[1] - c[1]), std::abs(p[2] - c[2]));
    EXPECT_FALSE(err < kFloatBrokenMin) << "float as-printed unexpectedly accurate: " << err;
  }
  // ... and at alpha = 1e-7, d^2 - 1 rounds to d^2, d - d~ = 0 and the result is not finite
  // (already from alpha ~ 1e-4 on in float).
  {
    auto p = indirect_D_closed_form_as_printed<float>(1e-7f);
    EXPECT_FALSE(std::isfinite(p[1]) && std::isfinite(p[2]));
    auto c = indirect_D_closed_form(1e-7);
    EXPECT_TRUE(std::isfinite(c[1]) && std::isfinite(c[2]));
  }
  // Even double does not save the printed form: at alpha = 1e-5 its D2 is off by > 1 (measured 374).
  {
    auto p = indirect_D_closed_form_as_printed<double>(1e-5);
    auto c = indirect_D_closed_form(1e-5);
    EXPECT_FALSE(std::abs(p[2] - c[2]) < 1.0);
  }
}

TEST(IndirectTables, PolynomialFitWithinFittingTolerance) {
  // The paper's fit (section 5, Figure 4) quotes relative squared errors of 0.00016% (D1) and
  // 0.00064% (D2). Measured against the exact D on alpha uniform in [0, 1]: 0.000179% and 0.000479%,
  // i.e. the printed coefficients are what the paper fitted. The largest absolute errors sit at the
  // ends of the fitted range: D0 4.8e-6 everywhere (0.28209 is y_00 = 0.2820948 rounded), D1 2.75e-3
  // and D2 5.42e-3, both at alpha = 1. Tolerances sit just above those measurements, so a wrong
  // coefficient, sign or power (which moves a curve by >= 1e-2 somewhere) fails.
  constexpr std::array<double, 3> kFitMaxAbsTol = {5e-6, 3e-3, 6e-3};
  constexpr std::array<double, 3> kFitRelSqTol = {0.0, 2.0e-6, 5.0e-6};  // 0.0002%, 0.0005%
  std::array<double, 3> max_err{}, sq_err{}, sq_ref{};
  for (int i = 0; i <= 1000; ++i) {
    double a = i / 1000.0;
    auto p = indirect_D_polynomial(a);
    auto c = indirect_D_closed_form(a);
    for (int l = 0; l < 3; ++l) {
      max_err[l] = std::max(max_err[l], std::abs(p[l] - c[l]));
      sq_err[l] += (p[l] - c[l]) * (p[l] - c[l]);
      sq_ref[l] += c[l] * c[l];
    }
  }
  for (int l = 0; l < 3; ++l) EXPECT_LT(max_err[l], kFitMaxAbsTol[l]) << "band " << l;
  for (int l = 1; l < 3; ++l) EXPECT_LT(sq_err[l] / sq_ref[l], kFitRelSqTol[l]) << "band " << l;
  // Guard against testing a copy of the exact D: the fit must show its (known, ~3e-3) error.
  constexpr double kFitIsNotExact = 1e-3;
  EXPECT_GT(max_err[1], kFitIsNotExact);
  EXPECT_GT(max_err[2], kFitIsNotExact);
}

// ---------------------------------------------------------------------------------------------
// M(theta)

int m_of(int i) {
  int l = band_of(i);
  return i - l * l - l;
}

TEST(IndirectTables, MIsBlockDiagonalInM) {
  for (int order : {3, 4, 6}) {
    const int n2 = num_coeffs(order);
    for (double a : kAlphas) {
      auto M = indirect_M(order, a);
      ASSERT_EQ(static_cast<int>(M.size()), n2 * n2);
      for (int j = 0; j < n2; ++j)
        for (int k = 0; k < n2; ++k) {
          ASSERT_TRUE(std::isfinite(M[j * n2 + k]));
          if (m_of(j) != m_of(k)) {
            EXPECT_EQ(M[j * n2 + k], 0.0) << "j " << j << " k " << k;
          }
        }
    }
  }
}

TEST(IndirectTables, MMatchesBruteForce2D) {
  // Full 2D surface quadrature with eval_basis for both factors (no symmetry used, so it also checks
  // that the off-block entries really vanish). M_jk is O(1) at most; measured agreement <= 2e-14,
  // tolerance as for D.
  constexpr double kBruteTol = 1e-12;
  for (int order : {3, 4, 6}) {
    const int n2 = num_coeffs(order);
    for (double a : {0.1, 0.5, 0.9, 0.999}) {
      std::vector<double> ref(n2 * n2, 0.0);
      std::array<double, kMaxCoeffs> ys{}, yq{};
      for_each_proxy_surface_node(a, [&](const Vec3<double>& s, const Vec3<double>& n, double ds) {
        eval_basis(order, s, ys.data());
        eval_basis(order, n, yq.data());
        for (int j = 0; j < n2; ++j)
          for (int k = 0; k < n2; ++k) ref[j * n2 + k] += ds * ys[j] * yq[k];
      });
      auto M = indirect_M(order, a);
      double worst = 0.0;
      for (int i = 0; i < n2 * n2; ++i) worst = std::max(worst, std::abs(M[i] - ref[i]));
      EXPECT_LT(worst, kBruteTol) << "order " << order << " alpha " << a;
    }
  }
}

TEST(IndirectTables, MRowZeroAndColumnZeroAreKnownOperators) {
  // Row j = 0: y_00 is constant, so M_{0,k} = y_00 int_cap y_k(q^) ds = y_00 omega D_l for k = (l, 0):
  // the averaged operator of eq. 14 is the DC row of eq. 16 (and is zero for m != 0).
  // Column k = 0: a constant radiance over the proxy gives M_{j,0} = y_00 int_cap y_j(s) ds, the
  // projection of the cap indicator: 2 pi y_00 int_C^1 y_l0 dmu, closed form through Legendre polynomials.
  // Scaled by S^2 (omega ~ pi S^2) so that small alphas are held to the same relative accuracy.
  // Row 0 against D: two evaluations of one integral family, measured <= 1e-15 relative.
  constexpr double kRowTol = 1e-12;
  // Column 0 against the Legendre closed form: P_{l-1}(C) - P_{l+1}(C) cancels to ~(2l+1)(1 - C) as
  // C -> 1, losing ~1e-16 / S^2 relative: 1e-10 at alpha = 1e-3 (the smallest alpha checked for l > 0).
  constexpr double kColumnTol = 1e-9;
  // (M L~)_0 / (y_00 omega) = D . L~ for random L~ in [-1, 1]^n2: a sum of n2 = 36 terms of the above.
  constexpr double kApplyTol = 1e-11;
  const double y00 = 1.0 / (2.0 * std::sqrt(kPi));
  const int order = 6, n2 = num_coeffs(order);
  for (double a : kAlphas) {
    if (a == 0.0) continue;
    const double C = cos_of(a), omega = 2.0 * kPi * a * a / (1.0 + C), scale = a * a;
    auto M = indirect_M(order, a);
    auto D = indirect_D_quadrature(order, a);
    for (int k = 0; k < n2; ++k) {
      double expect = m_of(k) == 0 ? y00 * omega * D[band_of(k)] : 0.0;
      EXPECT_NEAR(M[k] / scale, expect / scale, kRowTol) << "alpha " << a << " k " << k;
    }
    for (int j = 0; j < n2; ++j) {
      if (m_of(j) != 0) {
        EXPECT_EQ(M[j * n2], 0.0);
        continue;
      }
      int l = band_of(j);
      if (l > 0 && a < 1e-3) continue;  // the closed form itself is not accurate enough there
      // l = 0: int_C^1 y_00 dmu = y_00 (1 - C) = y_00 S^2 / (1 + C), written without cancellation.
      double integral = l == 0 ? y00 * a * a / (1.0 + C) : cap_zonal_integral(l, C);
      EXPECT_NEAR(M[j * n2] / scale, 2.0 * kPi * y00 * integral / scale, kColumnTol) << "alpha " << a << " j " << j;
    }
    // Any L~: (M L~)_0 / (y_00 omega) = D . L~ (only the m = 0 coefficients of L~ reach D).
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> L(n2);
    for (double& v : L) v = u(rng);
    double row0 = 0.0, dl = 0.0;
    for (int k = 0; k < n2; ++k) row0 += M[k] * L[k];
    for (int l = 0; l < order; ++l) dl += D[l] * L[index(l, 0)];
    EXPECT_NEAR(row0 / (y00 * omega), dl, kApplyTol) << "alpha " << a;
  }
}

TEST(IndirectTables, MLimits) {
  // alpha = 0: empty cap, M = 0. alpha = 1: the proxy touches p, every ray of the upper hemisphere
  // hits q = p with normal -z: M_jk = (int_{z>0} y_j) y_k(-z), nonzero only for m_j = m_k = 0.
  const int order = 4, n2 = num_coeffs(order);
  auto M0 = indirect_M(order, 0.0);
  for (double v : M0) EXPECT_EQ(v, 0.0);
  auto M1 = indirect_M(order, 1.0);
  for (int j = 0; j < n2; ++j)
    for (int k = 0; k < n2; ++k) {
      double expect = 0.0;
      if (m_of(j) == 0 && m_of(k) == 0)
        expect = 2.0 * kPi * cap_zonal_integral(band_of(j), 0.0) * y_l0(band_of(k), -1.0);
      EXPECT_NEAR(M1[j * n2 + k], expect, kExactTol) << "j " << j << " k " << k;
    }
  // alpha = 1e-7: |M_jk| <= omega max|y_j| max|y_k| ~ pi alpha^2 * 0.5 = 1.6e-14: finite and tiny.
  constexpr double kTinyCapBound = 1e-13;
  auto Ms = indirect_M(order, 1e-7);
  for (double v : Ms) EXPECT_LT(std::abs(v), kTinyCapBound);
}

// ---------------------------------------------------------------------------------------------
// w_theta (paper 001 eqs. 16-18)

TEST(IndirectTables, SphericalLightPrintedInclinationMatchesGeometry) {
  // Derivation check of eq. 17-18: the printed sin(atan((1 - S cos a)/(S sin a)) - a) equals the
  // inclination measured in 3D (light centre at the origin, radius S, receiver at (0,0,1)) and the
  // simplified (cos a - S)/sqrt(1 - 2 S cos a + S^2) used by the implementation.
  constexpr double kTrigTol = 1e-13;  // a handful of ulps through atan/sin/sqrt
  for (double S : {0.1, 0.5, 0.9}) {
    for (double ang = 0.01; ang < std::acos(S); ang += 0.01) {
      double printed = std::sin(std::atan((1.0 - S * std::cos(ang)) / (S * std::sin(ang))) - ang);
      Vec3<double> n{std::sin(ang), 0.0, std::cos(ang)};
      Vec3<double> x{S * n.x, 0.0, S * n.z};
      Vec3<double> to_p = normalize(Vec3<double>{-x.x, -x.y, 1.0 - x.z});
      double geom = dot(n, to_p);
      double simple = (std::cos(ang) - S) / std::sqrt(1.0 - 2.0 * S * std::cos(ang) + S * S);
      EXPECT_NEAR(printed, geom, kTrigTol);
      EXPECT_NEAR(simple, geom, kTrigTol);
    }
  }
}

TEST(IndirectTables, SphericalLightWeightNormalisedAndLimits) {
  const double y00 = 1.0 / (2.0 * std::sqrt(kPi));
  // w_0 is a ratio of two sums over the same nodes with y_00 constant: a few ulps of 0.28.
  constexpr double kDcTol = 1e-15;
  for (int order = 2; order <= kMaxOrder; ++order) {
    // w integrates to 1 over the sphere, so w_0 = y_00 int w = y_00 exactly (up to rounding).
    for (double a : kAlphas) {
      auto w = spherical_light_weight_zh(order, a);
      ASSERT_EQ(static_cast<int>(w.size()), order);
      EXPECT_NEAR(w[0], y00, kDcTol) << "alpha " << a;
      for (double v : w) EXPECT_TRUE(std::isfinite(v));
    }
    // S = 0 (receiver infinitely far): cos gamma = max(0, cos a), w = clamped cosine / pi.
    auto cc = clamped_cosine_zh(order);
    auto w0 = spherical_light_weight_zh(order, 0.0);
    for (int l = 0; l < order; ++l) EXPECT_NEAR(w0[l], cc[l] / kPi, kExactTol) << "l " << l;
    // S = 1 (receiver on the surface): w -> delta at the point facing p, w_l = y_l0(+z).
    auto w1 = spherical_light_weight_zh(order, 1.0);
    for (int l = 0; l < order; ++l) EXPECT_NEAR(w1[l], y_l0(l, 1.0), kExactTol) << "l " << l;
    // Continuity at both ends: w moves by O(alpha) at 0 and by O(1 - alpha) at 1 (l^2 ~ 50 at most).
    constexpr double kEndTol = 1e-5;
    auto wa = spherical_light_weight_zh(order, 1e-7), wb = spherical_light_weight_zh(order, 1.0 - 1e-7);
    for (int l = 0; l < order; ++l) {
      EXPECT_NEAR(wa[l], w0[l], kEndTol);
      EXPECT_NEAR(wb[l], w1[l], kEndTol);
    }
  }
}

TEST(IndirectTables, SphericalLightWeightMatchesMpmath) {
  for (const Ref& r : kWRef) {
    auto w = spherical_light_weight_zh(8, r.alpha);
    for (int l = 0; l < 8; ++l) EXPECT_NEAR(w[l], r.v[l], kExactTol) << "alpha " << r.alpha << " l " << l;
  }
}

TEST(IndirectTables, SphericalLightWeightMatchesBruteForce2D) {
  // 3D brute force: light of radius S centred at the origin, receiver at (0,0,1); walk the sphere's
  // surface over the support z in [S, 1] (graded towards z = 1, where cos gamma peaks), measure the
  // inclination with vectors, normalise numerically, project with eval_basis (all m, to see that the
  // result is zonal). The clamp is at the support's edge, so the rule integrates a smooth function.
  constexpr double kBruteTol = 1e-12;
  for (double S : {0.1, 0.5, 0.9, 0.999}) {
    const double eps = 1.0 - S;
    TestRule r = graded(0.0, eps, std::min(eps / 8.0, eps * eps), 24);
    const int nphi = 24;
    std::vector<double> proj(kMaxCoeffs, 0.0);
    double total = 0.0;
    std::array<double, kMaxCoeffs> y{};
    for (std::size_t k = 0; k < r.x.size(); ++k) {
      double z = 1.0 - r.x[k], rho = std::sqrt((1.0 - z) * (1.0 + z));
      for (int j = 0; j < nphi; ++j) {
        double phi = 2.0 * kPi * (j + 0.5) / nphi;
        Vec3<double> n{rho * std::cos(phi), rho * std::sin(phi), z};
        Vec3<double> to_p = normalize(Vec3<double>{-S * n.x, -S * n.y, 1.0 - S * n.z});
        double cg = std::max(0.0, dot(n, to_p));
        double wgt = r.w[k] * (2.0 * kPi / nphi) * cg;
        total += wgt;
        eval_basis(kMaxOrder, n, y.data());
        for (int i = 0; i < kMaxCoeffs; ++i) proj[i] += wgt * y[i];
      }
    }
    for (int order = 2; order <= kMaxOrder; ++order) {
      auto w = spherical_light_weight_zh(order, S);
      for (int i = 0; i < num_coeffs(order); ++i) {
        double expect = m_of(i) == 0 ? w[band_of(i)] : 0.0;
        EXPECT_NEAR(proj[i] / total, expect, kBruteTol) << "S " << S << " i " << i;
      }
    }
  }
}

TEST(IndirectTables, RejectsBadArguments) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double a : {-0.1, 1.1, nan}) {
    EXPECT_THROW(indirect_D_quadrature(3, a), std::invalid_argument);
    EXPECT_THROW(indirect_D_closed_form(a), std::invalid_argument);
    EXPECT_THROW(indirect_M(3, a), std::invalid_argument);
    EXPECT_THROW(spherical_light_weight_zh(3, a), std::invalid_argument);
  }
  EXPECT_THROW(indirect_D_quadrature(0, 0.5), std::invalid_argument);
  EXPECT_THROW(indirect_M(kMaxOrder + 1, 0.5), std::invalid_argument);
  EXPECT_THROW(spherical_light_weight_zh(-1, 0.5), std::invalid_argument);
}

}  // namespace
}  // namespace softgi::sh
