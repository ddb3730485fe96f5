// softgi SH core: conventions, indexing and basis evaluation.
//
// Conventions (docs/sh.md, "Conventions", states them in full; every module keeps them):
//  - Real spherical harmonics, orthonormal over the unit sphere, order n = bands 0..n-1, n*n coefficients.
//  - Single index i = l*l + l + m, m = -l..l.
//  - No Condon-Shortley phase: y_{1,-1} = c*y, y_{1,0} = c*z, y_{1,1} = c*x with c = sqrt(3/(4 pi)).
//    m > 0 uses cos(m phi), m < 0 uses sin(|m| phi); phi is measured from +x towards +y, theta from +z.
//  - Zonal harmonics (ZH) are circularly symmetric about +z and stored as n band coefficients g_l
//    (the m = 0 coefficients of the full vector).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace softgi::sh {

inline constexpr int kMinOrder = 1;  // order 1 (DC only) is used internally; the public range is 2..8
inline constexpr int kMaxOrder = 8;
inline constexpr int kMaxCoeffs = kMaxOrder * kMaxOrder;
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kSqrt4Pi = 3.54490770181103205460;  // DC coefficient of the constant function 1

constexpr int num_coeffs(int order) { return order * order; }
constexpr int index(int l, int m) { return l * l + l + m; }
constexpr int band_of(int i) {
  int l = 0;
  while ((l + 1) * (l + 1) <= i) ++l;
  return l;
}

// Throws std::invalid_argument naming `where` unless 1 <= order <= kMaxOrder.
void check_order(int order, const char* where);
// Throws std::invalid_argument naming `what`, the coefficient index and its value at the first NaN/Inf.
template <class T>
void check_finite(std::span<const T> v, const char* what);
// Throws std::invalid_argument unless v.size() >= num_coeffs(order).
template <class T>
void check_size(std::span<const T> v, int order, const char* what);

template <class T>
struct Vec3 {
  T x, y, z;
};
template <class T>
inline T dot(const Vec3<T>& a, const Vec3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class T>
inline Vec3<T> normalize(const Vec3<T>& a) {
  T len = std::sqrt(dot(a, a));
  return {a.x / len, a.y / len, a.z / len};
}

// Evaluates all n*n basis functions at the unit direction s (not re-normalised) into out[0..n*n).
// Polynomial recurrence in (x, y, z): no trigonometric calls, valid at the poles.
template <class T>
void eval_basis(int order, const Vec3<T>& s, T* out);

// sqrt(4 pi / (2l + 1)): the factor of the ZH rotation rule and of convolution (paper 000 eqs. 7-8).
inline double zh_rotation_factor(int l) { return std::sqrt(4.0 * kPi / (2.0 * l + 1.0)); }

// --- Zonal harmonics -------------------------------------------------------------------------
// ZH rotation rule (paper 004 section 6.1; paper 000 eq. 8): the full SH vector of the ZH function
// zh (n band coefficients about +z) turned to axis `dir` (unit):  f_lm = sqrt(4pi/(2l+1)) zh_l y_lm(dir).
template <class T>
void zh_rotate(int order, const T* zh, const Vec3<T>& dir, T* out);

// Convolution with a ZH kernel (paper 000 eq. 7): out_lm = sqrt(4pi/(2l+1)) k_l f_lm.
template <class T>
void zh_convolve(int order, const T* f, const T* kernel_zh, T* out);

// ZH of the clamped cosine max(0, s.z), bands 0..order-1, in double (exact quadrature).
std::vector<double> clamped_cosine_zh(int order);

// H(N) = (1/pi) int max(s.N, 0) y(s) ds (paper 004 eq. 9): the diffuse transfer vector for normal N.
template <class T>
void irradiance_weight(int order, const Vec3<T>& normal, T* out);

// L~ = L convolved with the clamped cosine (paper 000 section 3): irradiance L~(N) = L~ . y(N).
template <class T>
void irradiance_env(int order, const T* light, T* out);

// --- Windowing (paper 004 section 7) ---------------------------------------------------------
// Cosine window a_l = cos(pi/2 * l/h); h = 2n works well (paper). Bands l >= h are zeroed.
double window_factor(int l, double h);
template <class T>
void apply_window(int order, T* f, double h);

// --- Projection and reconstruction --------------------------------------------------------------
// f(s) reconstructed from its coefficients (paper 004 eq. 2).
template <class T>
T reconstruct(int order, const T* f, const Vec3<T>& s);

// Product quadrature on the sphere: Gauss-Legendre in z times uniform phi. With `bands` = B it
// integrates every polynomial of degree < 2B exactly (B Gauss nodes in z, 2B phi samples).
struct SphereQuadrature {
  std::vector<Vec3<double>> dirs;
  std::vector<double> weights;  // sum to 4 pi
};
SphereQuadrature make_sphere_quadrature(int bands);

// Projects a scalar function of direction (paper 004 eq. 1) with the quadrature rule.
template <class F>
std::vector<double> project(int order, const SphereQuadrature& q, F&& fn) {
  check_order(order, "sh::project");
  std::vector<double> out(num_coeffs(order), 0.0);
  std::array<double, kMaxCoeffs> y{};
  for (std::size_t k = 0; k < q.dirs.size(); ++k) {
    double v = fn(q.dirs[k]) * q.weights[k];
    eval_basis(order, q.dirs[k], y.data());
    for (int i = 0; i < num_coeffs(order); ++i) out[i] += v * y[i];
  }
  return out;
}

// Lat-long (equirectangular) environment maps, row-major, `channels` floats per pixel, row 0 at the
// top. Pixel (u, v) centre maps to theta = pi (v + 0.5) / H measured from +y (up), phi = 2 pi (u + 0.5) / W,
// direction (sin theta cos phi, cos theta, -sin theta sin phi): the +y-up convention of glTF scenes.
Vec3<double> latlong_direction(double u, double v, int width, int height);

// The continuous function a lat-long map stands for.
//  - Nearest: piecewise constant, pixel (u, v) on the spherical rectangle phi in 2 pi [u, u+1]/W,
//    theta in pi [v, v+1]/H (solid angle (phi1 - phi0)(cos theta0 - cos theta1)).
//  - Bilinear: bilinear in (phi, theta) between pixel centres, wrapping in u and clamping in v (above
//    the first and below the last row centre the row itself): the lookup of scene::Environment::radiance.
enum class LatLongFilter { Nearest, Bilinear };

// Projection of the map's `filter` reconstruction onto the basis (paper 004 eq. 1), integrated exactly
// over every pixel (closed form in phi, Gauss-Legendre in theta to double rounding) for every map size:
// a constant map gives (sqrt(4 pi) c, 0, ...) even at 1x1. Returns channels * n*n coefficients,
// channel-major. Throws std::invalid_argument for a bad size or order, or a non-finite pixel (named).
std::vector<double> project_latlong(int order, const float* pixels, int width, int height, int channels,
                                    LatLongFilter filter = LatLongFilter::Bilinear);

}  // namespace softgi::sh
