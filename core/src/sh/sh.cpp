#include "softgi/sh/sh.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "softgi/sh/quadrature.hpp"

namespace softgi::sh {

void check_order(int order, const char* where) {
  if (order < kMinOrder || order > kMaxOrder) {
    std::ostringstream os;
    os << where << ": SH order " << order << " is outside the supported range [" << kMinOrder << ", "
       << kMaxOrder << "]";
    throw std::invalid_argument(os.str());
  }
}

template <class T>
void check_finite(std::span<const T> v, const char* what) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      std::ostringstream os;
      os << what << ": coefficient " << i << " is " << v[i] << " (SH inputs must be finite)";
      throw std::invalid_argument(os.str());
    }
  }
}
template void check_finite<float>(std::span<const float>, const char*);
template void check_finite<double>(std::span<const double>, const char*);

template <class T>
void check_size(std::span<const T> v, int order, const char* what) {
  if (v.size() < static_cast<std::size_t>(num_coeffs(order))) {
    std::ostringstream os;
    os << what << ": " << v.size() << " coefficients given, order " << order << " needs " << num_coeffs(order);
    throw std::invalid_argument(os.str());
  }
}
template void check_size<float>(std::span<const float>, int, const char*);
template void check_size<double>(std::span<const double>, int, const char*);

namespace {
// K_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), times sqrt(2) for m > 0, for the polynomial form
// y_lm = K_lm * Pbar_l^m(z) * {cos, sin}-polynomial in (x, y), where Pbar_l^m = P_l^m / sin^m(theta)
// without Condon-Shortley phase.
struct NormTable {
  double k[kMaxOrder][kMaxOrder];
  NormTable() {
    for (int l = 0; l < kMaxOrder; ++l) {
      for (int m = 0; m <= l; ++m) {
        double ratio = 1.0;  // (l-m)!/(l+m)!
        for (int t = l - m + 1; t <= l + m; ++t) ratio /= t;
        double v = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi) * ratio);
        k[l][m] = m == 0 ? v : v * std::sqrt(2.0);
      }
    }
  }
};
const NormTable& norms() {
  static const NormTable t;
  return t;
}
}  // namespace

template <class T>
void eval_basis(int order, const Vec3<T>& s, T* out) {
  const NormTable& nt = norms();
  const T x = s.x, y = s.y, z = s.z;
  // cm, sm: r^m sin^m(theta) cos(m phi), sin(m phi) as polynomials in x, y.
  T cm = 1, sm = 0;
  T pmm = 1;  // Pbar_m^m = (2m-1)!!
  for (int m = 0; m < order; ++m) {
    if (m > 0) {
      T c2 = x * cm - y * sm;
      T s2 = x * sm + y * cm;
      cm = c2;
      sm = s2;
      pmm *= T(2 * m - 1);
    }
    T p_prev2 = 0, p_prev = pmm;  // Pbar_{l-2}^m, Pbar_{l-1}^m
    for (int l = m; l < order; ++l) {
      T p;
      if (l == m) {
        p = pmm;
      } else if (l == m + 1) {
        p = T(2 * m + 1) * z * pmm;
      } else {
        p = (T(2 * l - 1) * z * p_prev - T(l + m - 1) * p_prev2) / T(l - m);
      }
      if (l > m) {
        p_prev2 = p_prev;
        p_prev = p;
      }
      const T k = static_cast<T>(nt.k[l][m]);
      if (m == 0) {
        out[index(l, 0)] = k * p;
      } else {
        out[index(l, m)] = k * p * cm;
        out[index(l, -m)] = k * p * sm;
      }
    }
  }
}
template void eval_basis<float>(int, const Vec3<float>&, float*);
template void eval_basis<double>(int, const Vec3<double>&, double*);

template <class T>
void zh_rotate(int order, const T* zh, const Vec3<T>& dir, T* out) {
  eval_basis(order, dir, out);
  for (int l = 0; l < order; ++l) {
    const T f = static_cast<T>(zh_rotation_factor(l)) * zh[l];
    for (int m = -l; m <= l; ++m) out[index(l, m)] *= f;
  }
}
template void zh_rotate<float>(int, const float*, const Vec3<float>&, float*);
template void zh_rotate<double>(int, const double*, const Vec3<double>&, double*);

template <class T>
void zh_convolve(int order, const T* f, const T* kernel_zh, T* out) {
  for (int l = 0; l < order; ++l) {
    const T k = static_cast<T>(zh_rotation_factor(l)) * kernel_zh[l];
    for (int m = -l; m <= l; ++m) out[index(l, m)] = k * f[index(l, m)];
  }
}
template void zh_convolve<float>(int, const float*, const float*, float*);
template void zh_convolve<double>(int, const double*, const double*, double*);

std::vector<double> clamped_cosine_zh(int order) {
  check_order(order, "clamped_cosine_zh");
  // g_l = 2 pi K_l0 int_0^1 mu P_l(mu) dmu; the integrand is a polynomial of degree <= order,
  // so Gauss-Legendre with `order` nodes on [0, 1] is exact.
  const GaussLegendre& gl = gauss_legendre(order + 1);
  std::vector<double> out(order, 0.0);
  std::array<double, kMaxCoeffs> y{};
  for (std::size_t i = 0; i < gl.nodes.size(); ++i) {
    double mu = 0.5 * (gl.nodes[i] + 1.0), w = 0.5 * gl.weights[i];
    eval_basis(order, Vec3<double>{std::sqrt(std::max(0.0, 1.0 - mu * mu)), 0.0, mu}, y.data());
    for (int l = 0; l < order; ++l) out[l] += 2.0 * kPi * w * mu * y[index(l, 0)];
  }
  return out;
}

namespace {
template <class T>
const std::vector<T>& clamped_cosine_cached(int order) {
  static const auto table = [] {
    std::array<std::vector<T>, kMaxOrder + 1> t;
    for (int n = 1; n <= kMaxOrder; ++n) {
      auto d = clamped_cosine_zh(n);
      t[n].assign(d.begin(), d.end());
    }
    return t;
  }();
  return table[order];
}
}  // namespace

template <class T>
void irradiance_weight(int order, const Vec3<T>& normal, T* out) {
  check_order(order, "irradiance_weight");
  const auto& g = clamped_cosine_cached<T>(order);
  zh_rotate(order, g.data(), normal, out);
  for (int i = 0; i < num_coeffs(order); ++i) out[i] /= static_cast<T>(kPi);
}
template void irradiance_weight<float>(int, const Vec3<float>&, float*);
template void irradiance_weight<double>(int, const Vec3<double>&, double*);

template <class T>
void irradiance_env(int order, const T* light, T* out) {
  check_order(order, "irradiance_env");
  zh_convolve(order, light, clamped_cosine_cached<T>(order).data(), out);
}
template void irradiance_env<float>(int, const float*, float*);
template void irradiance_env<double>(int, const double*, double*);

double window_factor(int l, double h) {
  if (!(h > 0.0) || !std::isfinite(h)) throw std::invalid_argument("window_factor: window size h must be positive and finite");
  if (l >= h) return 0.0;
  return std::cos(kPi / 2.0 * (l / h));
}

template <class T>
void apply_window(int order, T* f, double h) {
  for (int l = 0; l < order; ++l) {
    const T a = static_cast<T>(window_factor(l, h));
    for (int m = -l; m <= l; ++m) f[index(l, m)] *= a;
  }
}
template void apply_window<float>(int, float*, double);
template void apply_window<double>(int, double*, double);

template <class T>
T reconstruct(int order, const T* f, const Vec3<T>& s) {
  std::array<T, kMaxCoeffs> y{};
  eval_basis(order, s, y.data());
  T v = 0;
  for (int i = 0; i < num_coeffs(order); ++i) v += f[i] * y[i];
  return v;
}
template float reconstruct<float>(int, const float*, const Vec3<float>&);
template double reconstruct<double>(int, const double*, const Vec3<double>&);

SphereQuadrature make_sphere_quadrature(int bands) {
  if (bands < 1 || bands > 2048) throw std::invalid_argument("make_sphere_quadrature: bands " + std::to_string(bands) + " outside [1, 2048]");
  const GaussLegendre& gl = gauss_legendre(bands);
  const int nphi = 2 * bands;
  SphereQuadrature q;
  q.dirs.reserve(static_cast<std::size_t>(bands) * nphi);
  q.weights.reserve(q.dirs.capacity());
  for (int i = 0; i < bands; ++i) {
    double z = gl.nodes[i], r = std::sqrt(std::max(0.0, 1.0 - z * z));
    for (int j = 0; j < nphi; ++j) {
      double phi = 2.0 * kPi * (j + 0.5) / nphi;
      q.dirs.push_back({r * std::cos(phi), r * std::sin(phi), z});
      q.weights.push_back(gl.weights[i] * 2.0 * kPi / nphi);
    }
  }
  return q;
}

}  // namespace softgi::sh
