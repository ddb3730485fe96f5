// Tests for the general SH rotation (core/src/sh/rotation.cpp).
//
// Definition under test: with B = ShRotation(order, R), f' = B f reconstructs f'(s) = f(R^T s),
// the function turned by R (a lobe at d moves to R d). Every suite name starts with "Rotation".
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/sh/rotation.hpp"
#include "softgi/sh/sh.hpp"

namespace {

using softgi::sh::index;
using softgi::sh::kMaxOrder;
using softgi::sh::kPi;
using softgi::sh::Mat3;
using softgi::sh::num_coeffs;
using softgi::sh::ShRotation;
using V3 = softgi::sh::Vec3<double>;
namespace sh = softgi::sh;

// --- Tolerances ---------------------------------------------------------------------------------
// 3x3 matrix identities (Rodrigues, products, R from = to): a handful of roundings on O(1) values.
constexpr double kMat3Tol = 1e-14;
// Recurrence against the fitted reference. The reference solves a (2l+1)^2 system whose condition
// number is below 10 for the directions it picks, so its own error is ~1e-15; the recurrence
// accumulates ~l roundings per band. Observed max 1.0e-14 over orders 2..8; 1e-12 leaves margin
// without hiding a wrong sign or factor (the misprinted forms of the recurrence give O(0.5) errors).
constexpr double kReferenceTol = 1e-12;
// Group identities in double (composition, B B^T = I, closed forms): products of 15x15 blocks of
// O(1) entries, each entry carrying ~1e-15 error. Observed max 3.8e-15.
constexpr double kGroupTol = 1e-13;
// Reconstruction invariance: 64-term sums of O(1) coefficients times basis values up to ~1.5;
// values are O(10), each carrying ~64 roundings. Scaled by the coefficient 1-norm below.
// Observed max 3.4e-16 relative.
constexpr double kReconstructRelTol = 1e-13;
// ZH rotation rule against the general rotation: both are exact in exact arithmetic; differences
// are roundings on O(1) coefficients (the eval_basis recurrence and the SH recurrence). Observed 2.2e-15.
constexpr double kZonalTol = 1e-13;
// float apply against double apply: each output is a (2l+1)-term dot product (2l+1 <= 15) of float
// inputs with orthogonal-row weights, accumulated in double and rounded once, so the error is one
// float rounding of the result: <= FLT_EPSILON/2 * |out|. Allow 4 FLT_EPSILON times the row's input
// scale (max |f| in the band times sqrt(2l+1) bounds |out|) for slack. Observed 0.25.
constexpr double kFloatUlps = 4.0;

// Observed maxima go to the XML report (--gtest_output=xml) as test properties.
std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3e", v);
  return buf;
}

constexpr int kPerm[3] = {1, 2, 0};  // SH order (y, z, x) of band 1

std::mt19937_64& rng() {
  static std::mt19937_64 gen(0x50F761u);
  return gen;
}

V3 random_unit() {
  std::normal_distribution<double> n(0.0, 1.0);
  for (;;) {
    V3 v{n(rng()), n(rng()), n(rng())};
    double len = std::sqrt(sh::dot(v, v));
    if (len > 1e-3) return {v.x / len, v.y / len, v.z / len};
  }
}

Mat3 random_rotation() {
  std::uniform_real_distribution<double> a(0.0, 2.0 * kPi);
  return sh::rotation_from_axis_angle(random_unit(), a(rng()));
}

std::vector<double> random_coeffs(int order) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<double> f(num_coeffs(order));
  for (double& v : f) v = n(rng());
  return f;
}

V3 mul(const Mat3& r, const V3& s) {
  return {r[0][0] * s.x + r[0][1] * s.y + r[0][2] * s.z, r[1][0] * s.x + r[1][1] * s.y + r[1][2] * s.z,
          r[2][0] * s.x + r[2][1] * s.y + r[2][2] * s.z};
}

Mat3 identity3() { return Mat3{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}; }

double max_diff(const Mat3& a, const Mat3& b) {
  double e = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) e = std::max(e, std::abs(a[i][j] - b[i][j]));
  return e;
}

double max_diff(const V3& a, const V3& b) {
  return std::max({std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
}

double max_diff(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double e = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) e = std::max(e, std::abs(a[i] - b[i]));
  return e;
}

double det3(const Mat3& r) {
  return r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
         r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
}

void expect_proper_rotation(const Mat3& r) {
  EXPECT_LT(max_diff(sh::multiply(r, sh::transpose(r)), identity3()), kMat3Tol);
  EXPECT_NEAR(det3(r), 1.0, kMat3Tol);
}

// n x n row-major product.
std::vector<double> matmul(const std::vector<double>& a, const std::vector<double>& b, int n) {
  std::vector<double> c(std::size_t(n) * n, 0.0);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) {
      const double aik = a[std::size_t(i) * n + k];
      for (int j = 0; j < n; ++j) c[std::size_t(i) * n + j] += aik * b[std::size_t(k) * n + j];
    }
  return c;
}

std::vector<double> transposed(const std::vector<double>& a, int n) {
  std::vector<double> t(a.size());
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) t[std::size_t(j) * n + i] = a[std::size_t(i) * n + j];
  return t;
}

std::vector<double> identity(int n) {
  std::vector<double> e(std::size_t(n) * n, 0.0);
  for (int i = 0; i < n; ++i) e[std::size_t(i) * n + i] = 1.0;
  return e;
}

// A few rotations with special structure on top of the random ones: half turns (where the
// recurrence's P terms cancel hardest), a tiny angle, quarter turns about the axes.
std::vector<Mat3> test_rotations(int random_count) {
  std::vector<Mat3> rs;
  rs.push_back(identity3());
  rs.push_back(sh::rotation_from_axis_angle({1, 0, 0}, kPi));
  rs.push_back(sh::rotation_from_axis_angle({0, 1, 0}, kPi));
  rs.push_back(sh::rotation_from_axis_angle({0, 0, 1}, kPi));
  rs.push_back(sh::rotation_from_axis_angle({1, 1, 1}, kPi));
  rs.push_back(sh::rotation_from_axis_angle({0, 1, 0}, 0.5 * kPi));
  rs.push_back(sh::rotation_from_axis_angle({1, 0, 0}, -0.5 * kPi));
  rs.push_back(sh::rotation_from_axis_angle({0.3, -0.2, 0.9}, 1e-7));
  for (int i = 0; i < random_count; ++i) rs.push_back(random_rotation());
  return rs;
}

// --- 3x3 helpers -------------------------------------------------------------------------------

TEST(RotationMatrix3, AxisAngleMatchesClosedForm) {
  const double phi = 0.7, c = std::cos(phi), s = std::sin(phi);
  EXPECT_LT(max_diff(sh::rotation_from_axis_angle({0, 0, 1}, phi), Mat3{{{c, -s, 0}, {s, c, 0}, {0, 0, 1}}}),
            kMat3Tol);
  EXPECT_LT(max_diff(sh::rotation_from_axis_angle({2, 0, 0}, phi), Mat3{{{1, 0, 0}, {0, c, -s}, {0, s, c}}}),
            kMat3Tol)
      << "the axis is normalised";
  EXPECT_LT(max_diff(sh::rotation_from_axis_angle({0, 1, 0}, phi), Mat3{{{c, 0, s}, {0, 1, 0}, {-s, 0, c}}}),
            kMat3Tol);
  for (int i = 0; i < 20; ++i) {
    const V3 axis = random_unit();
    const Mat3 r = sh::rotation_from_axis_angle(axis, 2.1);
    expect_proper_rotation(r);
    EXPECT_LT(max_diff(mul(r, axis), axis), kMat3Tol) << "the axis is fixed";
  }
  EXPECT_THROW(sh::rotation_from_axis_angle({0, 0, 0}, 1.0), std::invalid_argument);
  EXPECT_THROW(sh::rotation_from_axis_angle({0, 0, 1}, NAN), std::invalid_argument);
}

TEST(RotationMatrix3, MultiplyAndTranspose) {
  const V3 axis = random_unit();
  const Mat3 a = sh::rotation_from_axis_angle(axis, 0.4);
  const Mat3 b = sh::rotation_from_axis_angle(axis, 1.1);
  EXPECT_LT(max_diff(sh::multiply(a, b), sh::rotation_from_axis_angle(axis, 1.5)), kMat3Tol);
  EXPECT_LT(max_diff(sh::transpose(a), sh::rotation_from_axis_angle(axis, -0.4)), kMat3Tol);
  const Mat3 m{{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}}};
  const Mat3 mt = sh::transpose(m);
  EXPECT_EQ(mt[0][2], 7.0);
  EXPECT_EQ(mt[2][0], 3.0);
  const Mat3 mm = sh::multiply(m, m);
  EXPECT_EQ(mm[0][0], 30.0);
  EXPECT_EQ(mm[1][2], 96.0);
  // Composition order: multiply(a, b) applies b first.
  const Mat3 rx = sh::rotation_from_axis_angle({1, 0, 0}, 0.5 * kPi);
  const Mat3 rz = sh::rotation_from_axis_angle({0, 0, 1}, 0.5 * kPi);
  EXPECT_LT(max_diff(mul(sh::multiply(rz, rx), V3{0, 1, 0}), mul(rz, mul(rx, V3{0, 1, 0}))), kMat3Tol);
}

// --- rotation_between ----------------------------------------------------------------------------

TEST(RotationBetween, Parallel) {
  std::vector<V3> dirs = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int i = 0; i < 10; ++i) dirs.push_back(random_unit());
  for (const V3& d : dirs) {
    const Mat3 r = sh::rotation_between(d, d);
    EXPECT_LT(max_diff(r, identity3()), kMat3Tol);
    EXPECT_LT(max_diff(mul(r, d), d), kMat3Tol);
  }
}

TEST(RotationBetween, Antiparallel) {
  double worst = 0.0;
  std::vector<V3> dirs = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  for (int i = 0; i < 10; ++i) dirs.push_back(random_unit());
  for (const V3& d : dirs) {
    const V3 opp{-d.x, -d.y, -d.z};
    const Mat3 r = sh::rotation_between(d, opp);
    expect_proper_rotation(r);
    worst = std::max(worst, max_diff(mul(r, d), opp));
    EXPECT_LT(max_diff(mul(r, d), opp), kMat3Tol);
  }
  // Nearly opposite: the axis is ill-determined, yet R from = to must hold to rounding.
  for (int i = 0; i < 10; ++i) {
    const V3 d = random_unit(), e = random_unit();
    const double eps = i < 5 ? 1e-9 : 1e-15;
    const V3 to = sh::normalize(V3{-d.x + eps * e.x, -d.y + eps * e.y, -d.z + eps * e.z});
    const Mat3 r = sh::rotation_between(d, to);
    expect_proper_rotation(r);
    worst = std::max(worst, max_diff(mul(r, d), to));
    EXPECT_LT(max_diff(mul(r, d), to), kMat3Tol);
  }
  RecordProperty("max_error", sci(worst));
}

TEST(RotationBetween, GenericIsShortestArc) {
  double worst = 0.0;
  for (int i = 0; i < 50; ++i) {
    const V3 a = random_unit(), b = random_unit();
    const Mat3 r = sh::rotation_between(a, b);
    expect_proper_rotation(r);
    worst = std::max(worst, max_diff(mul(r, a), b));
    EXPECT_LT(max_diff(mul(r, a), b), kMat3Tol);
    // Shortest arc: the axis is a x b and the angle acos(a.b), so trace = 1 + 2 a.b.
    const V3 axis{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
    EXPECT_LT(max_diff(mul(r, axis), axis), kMat3Tol);
    EXPECT_NEAR(r[0][0] + r[1][1] + r[2][2], 1.0 + 2.0 * sh::dot(a, b), kMat3Tol);
  }
  RecordProperty("max_error", sci(worst));
  // Non-unit inputs are normalised; zero vectors are rejected.
  const Mat3 r = sh::rotation_between({0, 0, 3}, {0, 2, 0});
  EXPECT_LT(max_diff(mul(r, V3{0, 0, 1}), V3{0, 1, 0}), kMat3Tol);
  EXPECT_THROW(sh::rotation_between({0, 0, 0}, {0, 0, 1}), std::invalid_argument);
  EXPECT_THROW(sh::rotation_between({0, 0, 1}, {0, NAN, 0}), std::invalid_argument);
}

// --- ShRotation ----------------------------------------------------------------------------------

TEST(Rotation, MatchesReference) {
  double worst = 0.0;
  for (int order = 2; order <= kMaxOrder; ++order) {
    for (const Mat3& r : test_rotations(12)) {
      const double e = max_diff(ShRotation(order, r).dense(), sh::rotation_reference_dense(order, r));
      worst = std::max(worst, e);
      EXPECT_LT(e, kReferenceTol) << "order " << order;
    }
  }
  RecordProperty("max_error", sci(worst));
}

TEST(Rotation, BandOneIsPermutedMatrix) {
  const Mat3 r = random_rotation();
  const ShRotation b(kMaxOrder, r);
  EXPECT_EQ(b.order(), kMaxOrder);
  EXPECT_EQ(b.element(0, 0, 0), 1.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(b.element(1, i - 1, j - 1), r[kPerm[i]][kPerm[j]]);
}

TEST(Rotation, ReconstructionInvariance) {
  // f'(R s) = f(s): the turned function at the turned direction.
  double worst = 0.0;
  for (int order : {2, 3, 5, kMaxOrder}) {
    const int n = num_coeffs(order);
    for (const Mat3& r : test_rotations(8)) {
      const std::vector<double> f = random_coeffs(order);
      std::vector<double> g(n);
      ShRotation(order, r).apply(f.data(), g.data());
      double norm1 = 0.0;
      for (double v : f) norm1 += std::abs(v);
      for (int k = 0; k < 20; ++k) {
        const V3 s = random_unit();
        const double e = std::abs(sh::reconstruct(order, g.data(), mul(r, s)) - sh::reconstruct(order, f.data(), s));
        worst = std::max(worst, e / norm1);
        EXPECT_LT(e, kReconstructRelTol * norm1) << "order " << order;
      }
    }
  }
  RecordProperty("max_error", sci(worst));
}

TEST(Rotation, LobeMovesToRotatedDirection) {
  // A lobe at d (the ZH rule) turned by R peaks at R d: B zh_rotate(d) == zh_rotate(R d).
  const int order = kMaxOrder;
  std::vector<double> zh(order);
  for (int l = 0; l < order; ++l) zh[l] = 1.0 / (1.0 + l);
  const V3 d = random_unit();
  const Mat3 r = random_rotation();
  std::vector<double> f(num_coeffs(order)), g(num_coeffs(order)), expected(num_coeffs(order));
  sh::zh_rotate(order, zh.data(), d, f.data());
  ShRotation(order, r).apply(f.data(), g.data());
  sh::zh_rotate(order, zh.data(), mul(r, d), expected.data());
  EXPECT_LT(max_diff(g, expected), kZonalTol);
}

TEST(Rotation, Composition) {
  double worst = 0.0;
  for (int order : {2, 4, kMaxOrder}) {
    const int n = num_coeffs(order);
    for (int i = 0; i < 10; ++i) {
      const Mat3 r1 = random_rotation(), r2 = random_rotation();
      const std::vector<double> prod = matmul(ShRotation(order, r1).dense(), ShRotation(order, r2).dense(), n);
      const double e = max_diff(ShRotation(order, sh::multiply(r1, r2)).dense(), prod);
      worst = std::max(worst, e);
      EXPECT_LT(e, kGroupTol) << "order " << order;
      // Inverse: B(R^T) = B(R)^T.
      EXPECT_LT(max_diff(ShRotation(order, sh::transpose(r1)).dense(), transposed(ShRotation(order, r1).dense(), n)),
                kGroupTol);
    }
  }
  RecordProperty("max_error", sci(worst));
}

TEST(Rotation, Orthogonal) {
  double worst = 0.0;
  for (const Mat3& r : test_rotations(20)) {
    const ShRotation b(kMaxOrder, r);
    for (int l = 0; l < kMaxOrder; ++l) {
      const int dim = 2 * l + 1;
      const std::vector<double> blk(b.band(l), b.band(l) + dim * dim);
      const double e = max_diff(matmul(blk, transposed(blk, dim), dim), identity(dim));
      worst = std::max(worst, e);
      EXPECT_LT(e, kGroupTol) << "band " << l;
    }
  }
  RecordProperty("max_error", sci(worst));
}

TEST(Rotation, IdentityGivesIdentity) {
  for (int order = 1; order <= kMaxOrder; ++order) {
    EXPECT_LT(max_diff(ShRotation(order, identity3()).dense(), identity(num_coeffs(order))), kGroupTol);
  }
}

TEST(Rotation, AboutZClosedForm) {
  // f(R^T s) for R = Rz(phi): the azimuth shifts by phi, so (y_m, y_-m) ~ (cos m phi_s, sin m phi_s)
  // turn as f'_m = cos(m phi) f_m - sin(m phi) f_-m, f'_-m = sin(m phi) f_m + cos(m phi) f_-m.
  for (double phi : {0.3, -1.2, 0.5 * kPi, kPi, 2.9}) {
    const ShRotation b(kMaxOrder, sh::rotation_from_axis_angle({0, 0, 1}, phi));
    for (int l = 0; l < kMaxOrder; ++l) {
      for (int mr = -l; mr <= l; ++mr) {
        for (int mc = -l; mc <= l; ++mc) {
          const int m = std::abs(mr);
          double expected = 0.0;
          if (mr == 0 && mc == 0) {
            expected = 1.0;
          } else if (mc == mr) {
            expected = std::cos(m * phi);
          } else if (mc == -mr) {
            expected = mr > 0 ? -std::sin(m * phi) : std::sin(m * phi);
          }
          EXPECT_NEAR(b.element(l, mr, mc), expected, kGroupTol) << "l " << l << " m " << mr << " m' " << mc;
        }
      }
    }
  }
}

TEST(Rotation, ZonalConsistency) {
  // A ZH vector about +z turned onto d by rotation_between(z, d) equals the ZH rotation rule.
  double worst = 0.0;
  std::vector<V3> dirs = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}};
  for (int i = 0; i < 20; ++i) dirs.push_back(random_unit());
  for (int order : {2, 3, kMaxOrder}) {
    const int n = num_coeffs(order);
    for (const V3& d : dirs) {
      std::vector<double> zh(order), full(n, 0.0), turned(n), expected(n);
      std::normal_distribution<double> nd(0.0, 1.0);
      for (int l = 0; l < order; ++l) full[index(l, 0)] = zh[l] = nd(rng());
      ShRotation(order, sh::rotation_between({0, 0, 1}, d)).apply(full.data(), turned.data());
      sh::zh_rotate(order, zh.data(), d, expected.data());
      const double e = max_diff(turned, expected);
      worst = std::max(worst, e);
      EXPECT_LT(e, kZonalTol) << "order " << order;
    }
  }
  RecordProperty("max_error", sci(worst));
}

TEST(Rotation, ApplyMatchesDense) {
  const int order = kMaxOrder, n = num_coeffs(order);
  const ShRotation b(order, random_rotation());
  const std::vector<double> f = random_coeffs(order);
  std::vector<double> out(n), expected(n, 0.0);
  b.apply(f.data(), out.data());
  const std::vector<double> d = b.dense();
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) expected[i] += d[std::size_t(i) * n + j] * f[j];
  EXPECT_LT(max_diff(out, expected), kGroupTol);
}

TEST(Rotation, FloatApplyMatchesDouble) {
  double worst_ulps = 0.0;
  for (int order : {2, 5, kMaxOrder}) {
    const int n = num_coeffs(order);
    for (int i = 0; i < 10; ++i) {
      const ShRotation b(order, random_rotation());
      std::vector<double> fd = random_coeffs(order), outd(n);
      std::vector<float> ff(n), outf(n);
      for (int k = 0; k < n; ++k) {
        ff[k] = float(fd[k]);
        fd[k] = double(ff[k]);  // same inputs for both paths
      }
      b.apply(fd.data(), outd.data());
      b.apply(ff.data(), outf.data());
      for (int l = 0; l < order; ++l) {
        double scale = 0.0;
        for (int m = -l; m <= l; ++m) scale = std::max(scale, std::abs(fd[index(l, m)]));
        scale *= std::sqrt(2.0 * l + 1.0);
        for (int m = -l; m <= l; ++m) {
          const double e = std::abs(double(outf[index(l, m)]) - outd[index(l, m)]);
          worst_ulps = std::max(worst_ulps, e / (FLT_EPSILON * scale));
          EXPECT_LE(e, kFloatUlps * FLT_EPSILON * scale) << "order " << order << " l " << l << " m " << m;
        }
      }
    }
  }
  RecordProperty("max_error_flt_eps", sci(worst_ulps));
}

TEST(Rotation, OrderOneIsDcOnly) {
  const ShRotation b(1, random_rotation());
  EXPECT_EQ(b.order(), 1);
  const std::vector<double> d = b.dense();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0], 1.0);
  float f = 2.5f, out = 0.0f;
  b.apply(&f, &out);
  EXPECT_EQ(out, 2.5f);
}

TEST(Rotation, RejectsBadInput) {
  const Mat3 r = random_rotation();
  EXPECT_THROW(ShRotation(0, r), std::invalid_argument);
  EXPECT_THROW(ShRotation(kMaxOrder + 1, r), std::invalid_argument);
  EXPECT_THROW(sh::rotation_reference_dense(0, r), std::invalid_argument);
  Mat3 scaled = r;
  for (auto& row : scaled)
    for (double& v : row) v *= 1.1;
  EXPECT_THROW(ShRotation(3, scaled), std::invalid_argument);
  Mat3 reflected = r;
  for (double& v : reflected[0]) v = -v;  // det -1
  EXPECT_THROW(ShRotation(3, reflected), std::invalid_argument);
  Mat3 bad = r;
  bad[1][2] = NAN;
  EXPECT_THROW(ShRotation(3, bad), std::invalid_argument);
}

}  // namespace
