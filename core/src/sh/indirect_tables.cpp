// Indirect-lighting operators of a spherical proxy / spherical light, as functions of the angular
// radius theta (alpha = sin theta):
//  - D(theta), the averaged indirect operator of paper 000 (Sloan et al. 2007) eq. 14, by graded
//    Gauss-Legendre quadrature, by the paper's order-3 closed form (as printed and rewritten stably)
//    and by the paper's polynomial fit (section 5);
//  - M(theta), the exact indirect operator of paper 000 eq. 16;
//  - w_theta, the spherical-light average-radiance weight of paper 001 (Guerrero et al. 2008)
//    eqs. 16-18.
// Derivations are in docs/sh_indirect_tables.md; every formula here was checked against sympy and
// against brute-force 2D quadrature (tests/unit/test_indirect_tables.cpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::sh {

namespace {

// Gauss nodes per panel. With the panel layout below (panels never wider than the distance to the
// integrands' nearest complex singularity) 32 nodes reach ~1e-15 relative; the tests compare with
// the closed form at 1e-12.
constexpr int kNodesPerPanel = 32;

void check_alpha(double alpha, const char* where) {
  if (!(alpha >= 0.0 && alpha <= 1.0))
    throw std::invalid_argument(std::string(where) + ": alpha = sin(theta) must lie in [0, 1], got " +
                                std::to_string(alpha));
}

// cos theta from sin theta without the cancellation of sqrt(1 - S^2) as S -> 1.
double cos_from_sin(double s) { return std::sqrt((1.0 - s) * (1.0 + s)); }

// A composite Gauss-Legendre rule on [a, b] as explicit nodes and weights. The same panel layout as
// sh::integrate() (geometric grading towards a, smallest panel a_scale, ratio 2), but the operators
// here need n to n^4 integrals of one integrand family, so the nodes are visited once and every
// coefficient accumulated at each node. Without grading (a_scale <= 0 or >= (b - a) / 4) it uses
// four uniform panels.
struct Rule {
  std::vector<double> x, w;
};
Rule graded_rule(double a, double b, double a_scale) {
  const GaussLegendre& gl = gauss_legendre(kNodesPerPanel);
  Rule r;
  auto panel = [&](double lo, double hi) {
    double half = 0.5 * (hi - lo), mid = 0.5 * (hi + lo);
    for (int i = 0; i < kNodesPerPanel; ++i) {
      r.x.push_back(mid + half * gl.nodes[i]);
      r.w.push_back(half * gl.weights[i]);
    }
  };
  double len = b - a;
  if (!(a_scale > 0.0) || a_scale >= 0.25 * len) {
    for (int p = 0; p < 4; ++p) panel(a + len * p / 4.0, a + len * (p + 1) / 4.0);
    return r;
  }
  panel(a, a + a_scale);
  double lo = a + a_scale, width = a_scale;
  while (lo < b) {
    double hi = std::min(b, lo + width);
    panel(lo, hi);
    lo = hi;
    width *= 2.0;
  }
  return r;
}

// The phi-free part A_lm of the real SH y_lm (sh.hpp conventions: orthonormal, no Condon-Shortley
// phase, m > 0 -> cos(m phi), m < 0 -> sin(|m| phi)):  y_lm = A_lm(z, rho) * trig(m phi), with
// A_lm = K_lm P_l^|m|(z) for m = 0 and sqrt(2) K_lm P_l^|m|(z) otherwise,
// K_lm = sqrt((2l+1)/(4 pi) (l-|m|)!/(l+|m|)!). rho = sqrt(1 - z^2) is passed in separately so that
// callers can supply it without cancellation. out[index(l, m)] for l < order; A_{l,-m} = A_{l,m}.
// Written independently of eval_basis() so that the tests' brute-force references (built on
// eval_basis) check these operators rather than reuse them.
void legendre_parts(int order, double z, double rho, double* out) {
  for (int m = 0; m < order; ++m) {
    // P_m^m = (2m-1)!! rho^m (no Condon-Shortley phase), then the upward recurrence in l.
    double pmm = 1.0;
    for (int k = 1; k <= m; ++k) pmm *= (2.0 * k - 1.0) * rho;
    double p_prev = 0.0, p_cur = pmm;
    for (int l = m; l < order; ++l) {
      if (l == m + 1) {
        p_prev = p_cur;
        p_cur = z * (2.0 * m + 1.0) * pmm;
      } else if (l > m + 1) {
        double p_next = ((2.0 * l - 1.0) * z * p_cur - (l + m - 1.0) * p_prev) / (l - m);
        p_prev = p_cur;
        p_cur = p_next;
      }
      // (l-m)!/(l+m)! as a product, exact enough for l < 8.
      double ratio = 1.0;
      for (int k = l - m + 1; k <= l + m; ++k) ratio /= k;
      double k_lm = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi) * ratio);
      double a = (m == 0 ? 1.0 : std::sqrt(2.0)) * k_lm * p_cur;
      out[index(l, m)] = a;
      out[index(l, -m)] = a;
    }
  }
}

// y_l0(z) for l < order.
void zonal_parts(int order, double z, double* out) {
  double p_prev = 0.0, p_cur = 1.0;
  for (int l = 0; l < order; ++l) {
    if (l == 1) {
      p_prev = 1.0;
      p_cur = z;
    } else if (l > 1) {
      double p_next = ((2.0 * l - 1.0) * z * p_cur - (l - 1.0) * p_prev) / l;
      p_prev = p_cur;
      p_cur = p_next;
    }
    out[l] = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi)) * p_cur;
  }
}

// The canonical proxy configuration of paper 000 section 5, in the variable x of the substitution
// u = sqrt(mu^2 - C^2) = S x (mu = s_z, S = sin theta, C = cos theta, x in [0, 1]):
//   mu      = sqrt(C^2 + S^2 x^2)                 ray direction's z
//   rho_s   = S sqrt(1 - x^2)                     ray direction's distance from the z axis
//   q^_z    = S (x^2 - 1) - x mu                  hit point's normal, z
//   rho_q   = (mu - S x) sqrt(1 - x^2)            hit point's normal, distance from the z axis
//   dmu     = S^2 x / mu dx
// No division by S anywhere, so S = 0 (a point proxy) and S = 1 (a proxy touching p) evaluate
// directly. The only non-smooth feature is the kink of mu at x ~ C / S (branch points x = +-i C/S),
// which becomes sharp as S -> 1: the rule is graded towards x = 0 with a_scale = C / S.
struct ProxyPoint {
  double mu, rho_s, qz, rho_q, jac_over_S2;  // jac_over_S2 = x / mu, so dmu = S^2 * jac_over_S2 dx
};
ProxyPoint proxy_point(double S, double C, double x) {
  ProxyPoint p;
  p.mu = std::sqrt(C * C + S * S * x * x);
  double r = std::sqrt((1.0 - x) * (1.0 + x));
  p.rho_s = S * r;
  p.qz = S * (x * x - 1.0) - x * p.mu;
  p.rho_q = (p.mu - S * x) * r;
  // mu = 0 only at x = 0 with C = 0, which no Gauss node hits; the limit there is 1/S = 1.
  p.jac_over_S2 = p.mu > 0.0 ? x / p.mu : 1.0;
  return p;
}

Rule proxy_rule(double S, double C) {
  // Grade only when the kink is sharper than a panel; S = 1 (C = 0) makes the integrands smooth
  // (piecewise constant in x), so no grading is needed there either.
  double a_scale = (S > 0.0 && C > 0.0) ? C / S : 0.0;
  return graded_rule(0.0, 1.0, a_scale);
}

}  // namespace

// --- D(theta), paper 000 eq. 14 -----------------------------------------------------------------
// D_l = (1/omega) int_cap y_l0(q^(s)) ds with omega = 2 pi (1 - C). y_l0(q^) depends on q^_z only,
// the phi integral gives 2 pi, and 2 pi / omega * S^2 = (1 + C) (since 1 - C = S^2 / (1 + C)):
//   D_l = (1 + C) int_0^1 y_l0(q^_z(x)) x / sqrt(C^2 + S^2 x^2) dx.
std::vector<double> indirect_D_quadrature(int order, double alpha) {
  check_order(order, "indirect_D_quadrature");
  check_alpha(alpha, "indirect_D_quadrature");
  const double S = alpha, C = cos_from_sin(S);
  Rule r = proxy_rule(S, C);
  std::vector<double> d(order, 0.0);
  std::array<double, kMaxOrder> y{};
  for (std::size_t k = 0; k < r.x.size(); ++k) {
    ProxyPoint p = proxy_point(S, C, r.x[k]);
    zonal_parts(order, p.qz, y.data());
    double w = r.w[k] * p.jac_over_S2;
    for (int l = 0; l < order; ++l) d[l] += w * y[l];
  }
  for (double& v : d) v *= (1.0 + C);
  return d;
}

// Stable rewrite of the closed form (derivation in docs/sh_indirect_tables.md): with
// d - d~ = tan(theta/2) = S / (1 + C) and 1 - C = S^2 / (1 + C), the printed expressions become
//   D_1 = -sqrt(3) / (6 sqrt(pi)) * [ (1 + C) + S (2 + C) / (1 + C) ]
//   D_2 =  sqrt(5) / (20 sqrt(pi)) * [ (1 + C) (4 S - C) + 3 (2 + C) / (1 + C) ]
// Neither divides by S, so both are finite at S = 0 (D_1 = -sqrt(3)/(3 sqrt(pi)), D_2 = sqrt(5)/(8 sqrt(pi)))
// and at S = 1 (y_l0(-z)). The only subtraction, 4 S - C, sits next to the term 3 (2+C)/(1+C) >= 3,
// so the absolute error stays at rounding level.
std::array<double, 3> indirect_D_closed_form(double alpha) {
  check_alpha(alpha, "indirect_D_closed_form");
  const double S = alpha, C = cos_from_sin(S);
  const double sqrt_pi = std::sqrt(kPi);
  double d0 = 1.0 / (2.0 * sqrt_pi);
  double d1 = -std::sqrt(3.0) / (6.0 * sqrt_pi) * ((1.0 + C) + S * (2.0 + C) / (1.0 + C));
  double d2 = std::sqrt(5.0) / (20.0 * sqrt_pi) * ((1.0 + C) * (4.0 * S - C) + 3.0 * (2.0 + C) / (1.0 + C));
  return {d0, d1, d2};
}

// Paper 000 section 5, the order-3 closed form literally: d = csc theta, d~ = sqrt(d^2 - 1). It is
// algebraically correct (it equals the quadrature to rounding in double for moderate alpha), but
// d - d~ and the numerators cancel catastrophically as alpha -> 0 (error ~d^3 ulps): in float D_2 is
// off by 3e-4 at alpha = 0.1, by 0.1 at 0.03 and by 3e4 at 1e-3, and the result is inf once d^2 - 1
// rounds to d^2 (alpha <~ 1e-4); even double loses D_2 entirely by alpha = 1e-5. Not guarded on purpose: it exists to
// show that failure.
template <class T>
std::array<T, 3> indirect_D_closed_form_as_printed(T alpha) {
  using std::sqrt;
  const T pi = static_cast<T>(kPi);
  const T d = T(1) / alpha;
  const T dt = sqrt(d * d - T(1));
  T d0 = T(1) / (T(2) * sqrt(pi));
  T d1 = -sqrt(T(3)) * (T(2) * d * d * d - T(2) * dt * d * d - dt + T(1)) / (T(6) * sqrt(pi) * d * (d - dt));
  T d2 = sqrt(T(5)) * (T(6) * d * d * d * d * d - T(6) * dt * d * d * d * d - T(3) * dt * d * d - dt + T(4)) /
         (T(20) * sqrt(pi) * d * d * (d - dt));
  return {d0, d1, d2};
}
template std::array<float, 3> indirect_D_closed_form_as_printed<float>(float);
template std::array<double, 3> indirect_D_closed_form_as_printed<double>(double);

// Paper 000 section 5 polynomial fit (Figure 4), coefficients as printed.
std::array<double, 3> indirect_D_polynomial(double alpha) {
  const double a = alpha;
  double d0 = 0.28209;
  double d1 = (0.08432 * a - 0.25073) * a - 0.32494;
  double d2 = ((-0.22230 * a + 0.22502) * a + 0.47398) * a + 0.15950;
  return {d0, d1, d2};
}

// --- M(theta), paper 000 eq. 16 -----------------------------------------------------------------
// M_jk = int_cap y_j(s) y_k(q^(s)) ds. The hit point q = t s (t > 0) and q^ = (q - c)/S have the same
// azimuth phi as s, so with y = A(z, rho) trig(m phi) the phi integral is
// int trig_j trig_k dphi = delta(m_j, m_k) * (2 pi if m = 0, else pi): M is block-diagonal in m
// (same m, same sign). What is left is 1D in mu, written in x as above:
//   M_jk = phi_factor(m) * S^2 int_0^1 A_j(mu, rho_s) A_k(q^_z, rho_q) x / mu dx.
// For m odd the factors rho_s^m rho_q^m = S^m (mu - S x)^m (1 - x^2)^m make the integrand smooth at x = 1.
std::vector<double> indirect_M(int order, double alpha) {
  check_order(order, "indirect_M");
  check_alpha(alpha, "indirect_M");
  const int n2 = num_coeffs(order);
  const double S = alpha, C = cos_from_sin(S);
  std::vector<double> M(static_cast<std::size_t>(n2) * n2, 0.0);
  if (S == 0.0) return M;  // empty cap
  Rule r = proxy_rule(S, C);
  std::array<double, kMaxCoeffs> as{}, aq{};
  for (std::size_t k = 0; k < r.x.size(); ++k) {
    ProxyPoint p = proxy_point(S, C, r.x[k]);
    legendre_parts(order, p.mu, p.rho_s, as.data());
    legendre_parts(order, p.qz, p.rho_q, aq.data());
    double w = r.w[k] * p.jac_over_S2;
    for (int lj = 0; lj < order; ++lj)
      for (int mj = -lj; mj <= lj; ++mj) {
        int j = index(lj, mj);
        double wj = w * as[j];
        for (int lk = std::abs(mj); lk < order; ++lk) {
          int kk = index(lk, mj);
          M[static_cast<std::size_t>(j) * n2 + kk] += wj * aq[kk];
        }
      }
  }
  for (int j = 0; j < n2; ++j) {
    int mj = j - band_of(j) * band_of(j) - band_of(j);
    double phi_factor = (mj == 0 ? 2.0 * kPi : kPi);
    for (int kk = 0; kk < n2; ++kk) M[static_cast<std::size_t>(j) * n2 + kk] *= phi_factor * S * S;
  }
  return M;
}

// --- w_theta, paper 001 eqs. 16-18 --------------------------------------------------------------
// A point of the light sphere (centre c, radius r, receiver p at distance r/S) at angle a from the
// axis c -> p has inclination towards p
//   cos gamma(a) = max(0, (cos a - S) / sqrt(1 - 2 S cos a + S^2)),
// which equals the printed sin(atan((1 - S cos a)/(S sin a)) - a) (eq. 17-18). It is positive for
// mu = cos a in (S, 1]. w = cos gamma / int cos gamma domega (eq. 16), and its ZH coefficients are
//   w_l = int_S^1 cosg(mu) y_l0(mu) dmu / int_S^1 cosg(mu) dmu.
// As S -> 1 the support [S, 1] shrinks to eps = 1 - S and cosg peaks at mu = 1 with width ~eps. With
// mu = 1 - eps v^2 (v in [0, 1]) and the common factor sqrt(eps) dropped from numerator and denominator:
//   cosg dmu  ~  g(v) dv,  g(v) = 2 v (1 - v^2) / sqrt(eps + 2 S v^2),
// which is bounded for every S in [0, 1] (at S = 1: sqrt(2) (1 - v^2)) and has a kink of width
// sqrt(eps / (2S)) at v = 0: the rule is graded there.
std::vector<double> spherical_light_weight_zh(int order, double alpha) {
  check_order(order, "spherical_light_weight_zh");
  check_alpha(alpha, "spherical_light_weight_zh");
  const double S = alpha, eps = 1.0 - S;
  double a_scale = (S > 0.0 && eps < 2.0 * S) ? std::sqrt(eps / (2.0 * S)) : 0.0;
  Rule r = graded_rule(0.0, 1.0, a_scale);
  std::vector<double> w(order, 0.0);
  double norm = 0.0;
  std::array<double, kMaxOrder> y{};
  for (std::size_t k = 0; k < r.x.size(); ++k) {
    double v = r.x[k];
    double g = r.w[k] * 2.0 * v * (1.0 - v * v) / std::sqrt(eps + 2.0 * S * v * v);
    zonal_parts(order, 1.0 - eps * v * v, y.data());
    norm += g;
    for (int l = 0; l < order; ++l) w[l] += g * y[l];
  }
  for (double& c : w) c /= norm;
  return w;
}

}  // namespace softgi::sh
