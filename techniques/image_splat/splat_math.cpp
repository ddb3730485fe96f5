// Paper 000 (Sloan, Govindaraju, Nowrouzezahrai, Snyder 2007): the coverage oracle and smooth
// clamping of section 4.1, and the canonical indirect operators of section 5 (eqs. 13-16).
// The per-pair indirect evaluator is in indirect_evaluator.cpp.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/sh/product.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"
#include "splat_math.hpp"

namespace softgi::techniques::image_splat {

namespace {

using sh::kPi;
using V3 = sh::Vec3<double>;

constexpr double kHalfPi = kPi / 2;

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw std::invalid_argument("image_splat::" + where + ": " + what);
}

void check_oracle_args(int order, double threshold, const char* where) {
  if (order < 2 || order > sh::kMaxOrder)
    fail(where, "order " + std::to_string(order) + " is outside 2.." + std::to_string(sh::kMaxOrder));
  if (!(threshold > 0.0) || !std::isfinite(threshold))
    fail(where, "threshold must be positive and finite, got " + std::to_string(threshold));
}

void check_theta(double theta, const char* where) {
  if (!(theta >= 0.0 && theta <= kHalfPi + 1e-12))
    fail(where, "half-angle theta = " + std::to_string(theta) + " rad is outside [0, pi/2]");
}

// ZH (about +z) of the proxy's own visibility V (paper 000 eq. 3): 1 inside the cap. The core
// function is the environment's visibility 1 - V (section 3, O_i = 1 - V_i).
std::vector<double> proxy_visibility_zh(int order, double theta) {
  std::vector<double> g = sh::cap_visibility_zh(order, theta);
  g[0] = sh::kSqrt4Pi - g[0];
  for (int l = 1; l < order; ++l) g[l] = -g[l];
  return g;
}

// Direction at angle a from +z in the xz plane.
V3 polar_dir(double a) { return V3{std::sin(a), 0.0, std::cos(a)}; }

// Fibonacci-spiral directions: near-uniform, deterministic.
std::vector<V3> sphere_dirs(int count) {
  std::vector<V3> d(static_cast<std::size_t>(count));
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / count;
    const double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
    d[static_cast<std::size_t>(i)] = V3{rho * std::cos(golden * i), rho * std::sin(golden * i), z};
  }
  return d;
}

// max over [a, b] of f: a scan of `steps` intervals, then golden-section search on the two
// intervals around the best sample (f is smooth: band-limited in the angle).
template <class F>
double maximise_1d(F&& f, double a, double b, int steps) {
  double best = -std::numeric_limits<double>::infinity();
  int best_i = 0;
  for (int i = 0; i <= steps; ++i) {
    const double v = f(a + (b - a) * i / steps);
    if (v > best) {
      best = v;
      best_i = i;
    }
  }
  double lo = a + (b - a) * std::max(0, best_i - 1) / steps;
  double hi = a + (b - a) * std::min(steps, best_i + 1) / steps;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < 60; ++it) {
    if (f1 < f2) {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = f(x2);
    } else {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = f(x1);
    }
  }
  return std::max({best, f1, f2});
}

// Order-n delta light towards +z (the peakiest light of order n, section 4.1): L_lm = c y_lm(z),
// scaled so that unshadowed shading with N = +z is H(z) . L = 1 (or its peak radiance L_n(z) = 1).
std::vector<double> unit_delta_light(int order, LightNormalisation norm) {
  const int n2 = sh::num_coeffs(order);
  std::vector<double> y(n2), h(n2);
  sh::eval_basis(order, V3{0, 0, 1}, y.data());
  sh::irradiance_weight(order, V3{0, 0, 1}, h.data());
  double s = 0.0;
  for (int i = 0; i < n2; ++i) s += (norm == LightNormalisation::UnitShading ? h[i] : y[i]) * y[i];
  for (double& v : y) v /= s;
  return y;
}

// sum_lm F_l y_lm(dir) x_lm with F_l = sqrt(4pi/(2l+1)) zh_l: the dot product of the ZH vector zh
// turned to `dir` (eq. 8) with x.
double rotated_zh_dot(int order, const std::vector<double>& zh, const V3& dir, const double* x) {
  std::array<double, sh::kMaxCoeffs> y{};
  sh::eval_basis(order, dir, y.data());
  double s = 0.0;
  for (int l = 0; l < order; ++l) {
    double b = 0.0;
    for (int m = -l; m <= l; ++m) b += y[sh::index(l, m)] * x[sh::index(l, m)];
    s += sh::zh_rotation_factor(l) * zh[l] * b;
  }
  return s;
}

// The environment light of the "specialised" oracle, per channel (double), checked, scaled so that
// the largest unshadowed shading over `normals` and channels is 1.
struct EnvLight {
  std::array<std::vector<double>, 3> L;
};
EnvLight normalised_env(int order, const std::vector<glm::vec3>& env, const std::vector<V3>& normals, LightNormalisation norm,
                        const char* where) {
  const int n2 = sh::num_coeffs(order);
  if (static_cast<int>(env.size()) != n2)
    fail(where, "env_sh has " + std::to_string(env.size()) + " coefficients, order " + std::to_string(order) +
                    " needs " + std::to_string(n2));
  EnvLight e;
  for (int c = 0; c < 3; ++c) {
    e.L[c].resize(n2);
    for (int i = 0; i < n2; ++i) {
      const double v = env[static_cast<std::size_t>(i)][c];
      if (!std::isfinite(v)) fail(where, "env_sh coefficient " + std::to_string(i) + " is not finite");
      e.L[c][i] = v;
    }
  }
  double peak = 0.0;
  std::vector<double> h(n2);
  for (const V3& nrm : normals) {
    if (norm == LightNormalisation::UnitShading)
      sh::irradiance_weight(order, nrm, h.data());
    else
      sh::eval_basis(order, nrm, h.data());
    for (int c = 0; c < 3; ++c) {
      double s = 0.0;
      for (int i = 0; i < n2; ++i) s += h[i] * e.L[c][i];
      peak = std::max(peak, s);
    }
  }
  if (!(peak > 0.0)) fail(where, "env_sh gives no positive shading / radiance in any direction (black environment)");
  for (auto& ch : e.L)
    for (double& v : ch) v /= peak;
  return e;
}

constexpr int kEnvNormals = 300;   // "a few hundred well-spread normals"
constexpr int kEnvBlockers = 300;  // blocker / proxy directions of the environment oracle
constexpr int kAngleSteps = 360;   // 0.5 degree scan over [0, pi] before golden-section refinement

// Shadow difference, delta light (section 4.1). With N = w = +z the shadowed shading of one blocker
// is H . (O * L) (order-n triple product); unshadowed is H . L = H . (1 * L), so the difference is
// H . ((1 - O) * L) = H . (V * L) = sum_j V_j P_j with P = H * L (Gamma is symmetric). V is the ZH of
// the proxy turned to the blocker direction b: only the angle between b and z matters.
struct ShadowDeltaOracle {
  int order;
  std::vector<double> P;
  ShadowDeltaOracle(int n, LightNormalisation norm) : order(n), P(sh::num_coeffs(n)) {
    std::vector<double> h(sh::num_coeffs(n));
    sh::irradiance_weight(n, V3{0, 0, 1}, h.data());
    const std::vector<double> L = unit_delta_light(n, norm);
    sh::TripleProduct::get(n).product(h.data(), L.data(), P.data());
  }
  double operator()(double theta) const {
    const std::vector<double> v = proxy_visibility_zh(order, theta);
    return maximise_1d([&](double b) { return std::abs(rotated_zh_dot(order, v, polar_dir(b), P.data())); }, 0.0, kPi,
                       kAngleSteps);
  }
};

// Shadow difference, environment light: the same with P(N, c) = H(N) * L_c, maximised over the
// normals and blocker directions. Q[(a * B + b) * 3 + c][l] = sum_m y_lm(b) P(N_a, c)_lm is
// precomputed so that one theta costs normals x blockers x 3 x n multiply-adds.
struct ShadowEnvOracle {
  int order;
  std::vector<double> Q;
  ShadowEnvOracle(int n, const std::vector<glm::vec3>& env, LightNormalisation norm) : order(n) {
    const std::vector<V3> normals = sphere_dirs(kEnvNormals), blockers = sphere_dirs(kEnvBlockers);
    const EnvLight e = normalised_env(n, env, normals, norm, "derive_eta_shadow");
    const int n2 = sh::num_coeffs(n);
    const sh::TripleProduct& tp = sh::TripleProduct::get(n);
    std::vector<double> yb(static_cast<std::size_t>(blockers.size()) * n2);
    for (std::size_t b = 0; b < blockers.size(); ++b) sh::eval_basis(n, blockers[b], yb.data() + b * n2);
    Q.assign(normals.size() * blockers.size() * 3 * n, 0.0);
    std::vector<double> h(n2), P(n2);
    for (std::size_t a = 0; a < normals.size(); ++a) {
      sh::irradiance_weight(n, normals[a], h.data());
      for (int c = 0; c < 3; ++c) {
        tp.product(h.data(), e.L[c].data(), P.data());
        for (std::size_t b = 0; b < blockers.size(); ++b) {
          double* q = Q.data() + ((a * blockers.size() + b) * 3 + c) * n;
          const double* y = yb.data() + b * n2;
          for (int l = 0; l < n; ++l) {
            double s = 0.0;
            for (int m = -l; m <= l; ++m) s += y[sh::index(l, m)] * P[sh::index(l, m)];
            q[l] = sh::zh_rotation_factor(l) * s;
          }
        }
      }
    }
  }
  double operator()(double theta) const {
    const std::vector<double> v = proxy_visibility_zh(order, theta);
    double best = 0.0;
    for (std::size_t k = 0; k < Q.size(); k += order) {
      double s = 0.0;
      for (int l = 0; l < order; ++l) s += v[l] * Q[k + l];
      best = std::max(best, std::abs(s));
    }
    return best;
  }
};

// Indirect difference (section 4.1 "similarly ... for indirect accumulation"): a proxy of
// half-angle theta in direction d, albedo 1, shows the radiance I = kappa V (eq. 15) with
// kappa = rot(D(theta), d) . L~ / pi (a diffuse surface of albedo 1 under irradiance L~ leaves
// radiance L~ / pi). Its whole contribution I . H(N) = kappa (V . H(N)) is the shading difference it
// makes. kappa depends only on the angle between d and the light, V . H(N) only on the angle between
// d and N, and both angles are free, so the maximum is the product of the two maxima.
double max_vis_dot_h(int order, double theta) {
  const std::vector<double> v = proxy_visibility_zh(order, theta);
  std::vector<double> h(sh::num_coeffs(order));
  sh::irradiance_weight(order, V3{0, 0, 1}, h.data());
  return maximise_1d([&](double b) { return std::abs(rotated_zh_dot(order, v, polar_dir(b), h.data())); }, 0.0, kPi,
                     kAngleSteps);
}

struct IndirectDeltaOracle {
  int order;
  std::vector<double> Lt;  // L~ of the unit delta light towards +z
  IndirectDeltaOracle(int n, LightNormalisation norm) : order(n), Lt(sh::num_coeffs(n)) {
    const std::vector<double> L = unit_delta_light(n, norm);
    sh::irradiance_env(n, L.data(), Lt.data());
  }
  double operator()(double theta) const {
    const std::vector<double> D = sh::indirect_D_quadrature(order, std::sin(theta));
    const double kmax = maximise_1d(
        [&](double g) { return std::abs(rotated_zh_dot(order, D, polar_dir(g), Lt.data())) / kPi; }, 0.0, kPi,
        kAngleSteps);
    return kmax * max_vis_dot_h(order, theta);
  }
};

struct IndirectEnvOracle {
  int order;
  std::vector<V3> dirs;
  std::array<std::vector<double>, 3> Lt;
  IndirectEnvOracle(int n, const std::vector<glm::vec3>& env, LightNormalisation norm)
      : order(n), dirs(sphere_dirs(kEnvBlockers)) {
    const EnvLight e = normalised_env(n, env, sphere_dirs(kEnvNormals), norm, "derive_eta_indirect");
    for (int c = 0; c < 3; ++c) {
      Lt[c].resize(sh::num_coeffs(n));
      sh::irradiance_env(n, e.L[c].data(), Lt[c].data());
    }
  }
  double operator()(double theta) const {
    const std::vector<double> D = sh::indirect_D_quadrature(order, std::sin(theta));
    double kmax = 0.0;
    for (const V3& d : dirs)
      for (int c = 0; c < 3; ++c) kmax = std::max(kmax, std::abs(rotated_zh_dot(order, D, d, Lt[c].data())) / kPi);
    return kmax * max_vis_dot_h(order, theta);
  }
};

// The largest theta whose difference stays <= threshold: scan up from 0 in `step` to the first
// sample above the threshold, then bisect between it and the sample before. When the difference is
// monotone this is the largest admissible theta; otherwise it is where the difference first exceeds
// (the conservative choice), and `monotone` says so.
template <class F>
EtaDerivation invert(int order, double threshold, const char* light, double step, F&& diff) {
  EtaDerivation r;
  r.order = order;
  r.threshold = threshold;
  r.light = light;
  double lo = 0.0, lo_val = 0.0;
  bool crossed = false;
  double hi = kHalfPi;
  const int steps = static_cast<int>(std::ceil(kHalfPi / step));
  for (int i = 1; i <= steps; ++i) {
    const double t = std::min(kHalfPi, i * step);
    const double v = diff(t);
    if (v > threshold) {
      hi = t;
      crossed = true;
      break;
    }
    if (v < lo_val) r.monotone = false;
    lo = t;
    lo_val = v;
  }
  if (crossed) {
    for (int it = 0; it < 60 && hi - lo > 1e-13; ++it) {
      const double mid = 0.5 * (lo + hi);
      const double v = diff(mid);
      if (v > threshold) {
        hi = mid;
      } else {
        if (v < lo_val) r.monotone = false;
        lo = mid;
        lo_val = v;
      }
    }
  }
  r.theta_deg = lo * 180.0 / kPi;
  r.max_difference = lo_val;
  r.eta = lo > 0.0 ? 1.0 / std::sin(lo) : std::numeric_limits<double>::infinity();
  return r;
}

constexpr double kDeltaScanStep = 0.05 * kPi / 180.0;  // fine: the delta oracle is cheap
constexpr double kEnvScanStep = 0.25 * kPi / 180.0;    // coarser: each env evaluation is ~1e6 multiply-adds

}  // namespace

EtaDerivation derive_eta_shadow(int order, double threshold, const std::vector<glm::vec3>* env_sh,
                                LightNormalisation norm) {
  check_oracle_args(order, threshold, "derive_eta_shadow");
  if (env_sh) {
    const ShadowEnvOracle o(order, *env_sh, norm);
    return invert(order, threshold, "environment", kEnvScanStep, o);
  }
  const ShadowDeltaOracle o(order, norm);
  return invert(order, threshold, "delta", kDeltaScanStep, o);
}

EtaDerivation derive_eta_indirect(int order, double threshold, const std::vector<glm::vec3>* env_sh,
                                  LightNormalisation norm) {
  check_oracle_args(order, threshold, "derive_eta_indirect");
  if (env_sh) {
    const IndirectEnvOracle o(order, *env_sh, norm);
    return invert(order, threshold, "environment", kEnvScanStep, o);
  }
  const IndirectDeltaOracle o(order, norm);
  return invert(order, threshold, "delta", kDeltaScanStep, o);
}

double shadow_difference(int order, double theta, const std::vector<glm::vec3>* env_sh, LightNormalisation norm) {
  check_oracle_args(order, 1.0, "shadow_difference");
  check_theta(theta, "shadow_difference");
  if (env_sh) return ShadowEnvOracle(order, *env_sh, norm)(theta);
  return ShadowDeltaOracle(order, norm)(theta);
}

double indirect_difference(int order, double theta, const std::vector<glm::vec3>* env_sh, LightNormalisation norm) {
  check_oracle_args(order, 1.0, "indirect_difference");
  check_theta(theta, "indirect_difference");
  if (env_sh) return IndirectEnvOracle(order, *env_sh, norm)(theta);
  return IndirectDeltaOracle(order, norm)(theta);
}

// --- Smooth clamping ------------------------------------------------------------------------------

namespace {
void check_clamp_args(const common::ZhTable& t, double eta, int ramp_rows, const char* where) {
  if (t.order < 1 || t.rows < 2 || !(t.scale > 0.0f) ||
      t.data.size() != static_cast<std::size_t>(t.rows) * 2 * t.order || t.band.size() != t.data.size())
    fail(where, "malformed ZhTable (order " + std::to_string(t.order) + ", rows " + std::to_string(t.rows) + ")");
  if (std::isnan(eta)) fail(where, "eta is NaN");
  if (ramp_rows < 0 || ramp_rows > t.rows) fail(where, "ramp_rows = " + std::to_string(ramp_rows) + " is outside 0..rows");
}
double smoothstep(double x) { return x * x * (3.0 - 2.0 * x); }
}  // namespace

double clamp_row_weight(const common::ZhTable& table, double eta, int ramp_rows, int row) {
  check_clamp_args(table, eta, ramp_rows, "clamp_row_weight");
  if (row < 0 || row >= table.rows) fail("clamp_row_weight", "row " + std::to_string(row) + " is outside the table");
  if (!(eta > 1.0) || std::isinf(eta)) return 1.0;
  // Section 4.1: the smallest supported half-angle is asin(1/eta). Row k sits at theta_k = k / scale.
  // Every row up to the first one at or above that angle is 0, so that linear interpolation gives
  // exactly 0 for every theta <= asin(1/eta); the next ramp_rows rows rise smoothly (C1 smoothstep)
  // to 1 (the paper weights "the 4 table entries around 1/eta").
  const double u = std::asin(1.0 / eta) * static_cast<double>(table.scale);
  const int k0 = static_cast<int>(std::ceil(u - 1e-9));
  if (row <= k0) return 0.0;
  const int j = row - k0;
  if (j > ramp_rows) return 1.0;
  return smoothstep(static_cast<double>(j) / (ramp_rows + 1));
}

common::ZhTable clamp_zh_table(const common::ZhTable& table, double eta, int ramp_rows) {
  check_clamp_args(table, eta, ramp_rows, "clamp_zh_table");
  common::ZhTable t = table;
  if (!(eta > 1.0) || std::isinf(eta)) return t;
  const int n = t.order;
  std::vector<float> vals(static_cast<std::size_t>(t.rows) * n);
  for (int k = 0; k < t.rows; ++k) {
    const double w = clamp_row_weight(table, eta, ramp_rows, k);
    for (int l = 0; l < n; ++l)
      vals[static_cast<std::size_t>(k) * n + l] =
          static_cast<float>(w * table.data[static_cast<std::size_t>(k) * 2 * n + 2 * l]);
  }
  // Slopes from the clamped values, the layout of common::make_zh_table (last row: slope 0).
  for (int k = 0; k < t.rows; ++k)
    for (int l = 0; l < n; ++l) {
      const float v = vals[static_cast<std::size_t>(k) * n + l];
      const float next = k + 1 < t.rows ? vals[static_cast<std::size_t>(k + 1) * n + l] : v;
      t.data[static_cast<std::size_t>(k) * 2 * n + 2 * l] = v;
      t.data[static_cast<std::size_t>(k) * 2 * n + 2 * l + 1] = next - v;
      t.band[static_cast<std::size_t>(l) * 2 * t.rows + k] = v;
      t.band[static_cast<std::size_t>(l) * 2 * t.rows + t.rows + k] = next - v;
    }
  return t;
}

// --- Indirect operators -----------------------------------------------------------------------------

const char* to_string(IndirectOperator op) {
  switch (op) {
    case IndirectOperator::PointSampled: return "point";
    case IndirectOperator::AveragedPolynomial: return "averaged_poly";
    case IndirectOperator::AveragedExact: return "averaged";
    case IndirectOperator::Exact: return "exact";
  }
  return "?";
}

IndirectOperator parse_indirect_operator(const std::string& s) {
  for (IndirectOperator op : {IndirectOperator::PointSampled, IndirectOperator::AveragedPolynomial,
                              IndirectOperator::AveragedExact, IndirectOperator::Exact})
    if (s == to_string(op)) return op;
  throw std::invalid_argument("image_splat: unknown indirect operator '" + s +
                              "' (expected point, averaged_poly, averaged or exact)");
}

std::vector<double> canonical_operator(IndirectOperator op, int order, double alpha) {
  if (order < 1 || order > sh::kMaxOrder)
    fail("canonical_operator", "order " + std::to_string(order) + " is outside 1.." + std::to_string(sh::kMaxOrder));
  if (!(alpha >= 0.0 && alpha <= 1.0))
    fail("canonical_operator", "alpha = sin(theta) must lie in [0, 1], got " + std::to_string(alpha));
  if (op == IndirectOperator::AveragedPolynomial && order != 3)
    fail("canonical_operator", "the paper's polynomial D (averaged_poly) exists for order 3 only, got order " +
                                   std::to_string(order));
  // eq. 16: M_jk = int v(s) y_j(s) y_k(q^(s)) ds.
  if (op == IndirectOperator::Exact) return sh::indirect_M(order, alpha);
  const int n2 = sh::num_coeffs(order);
  // Canonical V: the proxy-visibility ZH on +z, f_l0 = g_l (eq. 8 with y_l0(z) = sqrt((2l+1)/4pi)).
  const std::vector<double> vzh = proxy_visibility_zh(order, std::asin(alpha));
  std::vector<double> V(n2, 0.0), r(n2, 0.0);
  for (int l = 0; l < order; ++l) V[sh::index(l, 0)] = vzh[l];
  if (op == IndirectOperator::PointSampled) {
    // eq. 13: I = (L~ . y(-d)) V, d = +z.
    sh::eval_basis(order, V3{0, 0, -1}, r.data());
  } else {
    // eq. 15: I = (rot(D, d) . L~) V; rot(D, z)_l0 = sqrt(4pi/(2l+1)) D_l y_l0(z) = D_l (eq. 8).
    std::vector<double> D;
    if (op == IndirectOperator::AveragedPolynomial) {
      const auto p = sh::indirect_D_polynomial(alpha);
      D.assign(p.begin(), p.end());
    } else {
      D = sh::indirect_D_quadrature(order, alpha);
    }
    for (int l = 0; l < order; ++l) r[sh::index(l, 0)] = D[l];
  }
  std::vector<double> A(static_cast<std::size_t>(n2) * n2);
  for (int j = 0; j < n2; ++j)
    for (int k = 0; k < n2; ++k) A[static_cast<std::size_t>(j) * n2 + k] = V[j] * r[k];
  return A;
}

std::vector<OperatorError> operator_error_curve(int order, int samples) {
  if (order < 1 || order > sh::kMaxOrder)
    fail("operator_error_curve", "order " + std::to_string(order) + " is outside 1.." + std::to_string(sh::kMaxOrder));
  if (samples < 1 || samples > 100000)
    fail("operator_error_curve", "samples = " + std::to_string(samples) + " is outside 1..100000");
  auto frob = [](const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(s);
  };
  // Operators on L: A C with C = diag(sqrt(4pi/(2l+1)) g_cos,l) (eq. 7), i.e. column k scaled.
  const std::vector<double> gcos = sh::clamped_cosine_zh(order);
  auto onL = [&](std::vector<double> a) {
    const int n2 = sh::num_coeffs(order);
    for (int j = 0; j < n2; ++j)
      for (int k = 0; k < n2; ++k)
        a[static_cast<std::size_t>(j) * n2 + k] *= sh::zh_rotation_factor(sh::band_of(k)) * gcos[sh::band_of(k)];
    return a;
  };
  std::vector<OperatorError> out;
  for (int k = 1; k <= samples; ++k) {
    OperatorError e;
    e.alpha = static_cast<double>(k) / samples;
    const std::vector<double> M = canonical_operator(IndirectOperator::Exact, order, e.alpha);
    const std::vector<double> zero(M.size(), 0.0);
    const double norm = frob(M, zero);
    auto rel = [&](double a) { return norm > 0.0 ? a / norm : 0.0; };
    const std::vector<double> ML = onL(M);
    const double normL = frob(ML, zero);
    auto relL = [&](const std::vector<double>& a) { return normL > 0.0 ? frob(onL(a), ML) / normL : 0.0; };
    const std::vector<double> P = canonical_operator(IndirectOperator::PointSampled, order, e.alpha);
    const std::vector<double> A = canonical_operator(IndirectOperator::AveragedExact, order, e.alpha);
    e.point_abs = frob(P, M);
    e.point_rel = rel(e.point_abs);
    e.point_rel_L = relL(P);
    e.averaged_abs = frob(A, M);
    e.averaged_rel = rel(e.averaged_abs);
    e.averaged_rel_L = relL(A);
    if (order == 3) {
      const std::vector<double> AP = canonical_operator(IndirectOperator::AveragedPolynomial, order, e.alpha);
      e.averaged_poly_abs = frob(AP, M);
      e.averaged_poly_rel = rel(e.averaged_poly_abs);
      e.averaged_poly_rel_L = relL(AP);
    } else {
      e.averaged_poly_abs = e.averaged_poly_rel = e.averaged_poly_rel_L = -1.0;
    }
    out.push_back(e);
  }
  return out;
}

void ProxyList::push(const glm::vec3& c, float radius, const glm::vec3& a) {
  cx.push_back(c.x);
  cy.push_back(c.y);
  cz.push_back(c.z);
  r.push_back(radius);
  albedo.push_back(a);
}

}  // namespace softgi::techniques::image_splat
