// Lat-long environment maps: the pixel mapping and the SH projection of the map's reconstruction.
//
// The projection integrates the continuous function a renderer reads from the map (box or bilinear
// reconstruction over texels), not point samples at pixel centres: a centre sample weighted by the
// pixel's solid angle is exact for no basis function but y_00, and on a tiny map (1x1, 2x1, 4x2) it
// turns a constant map into large band-1..n-1 coefficients.
//
// The map axis is +y, so the basis is not separable in the map's (theta, phi). In the frame
// p = P d = (d.x, -d.z, d.y) the map's theta and phi are the standard polar angles about +z, where
// y_lm(theta, phi) = A_lm(theta) trig_m(phi) (docs/sh.md, "Conventions"). Both reconstructions are a
// tensor product a_v(theta) b_u(phi) of 1D kernels, so every coefficient of g(p) = f(P^T p) is
//   g_lm = sum_v [int a_v A_lm sin(theta) dtheta] [sum_u pixel(u, v) int b_u trig_m dphi],
// with the phi integrals in closed form and the theta integrals by Gauss-Legendre panels whose error
// is far below double rounding; the coefficients of f are then ShRotation(P^T) of g's.
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/rotation.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::sh {

namespace {

double sinc(double x) { return x == 0.0 ? 1.0 : std::sin(x) / x; }

// One theta interval on which the reconstruction is (1 - t) row(v0) + t row(v1), t running linearly
// from 0 at `a` to `slope * (b - a)` at `b` (slope 0: a single row).
struct Piece {
  double a, b;
  int v0, v1;
  double slope;
};

// Theta pieces of the reconstruction. Box: row v on [pi v/H, pi (v+1)/H]. Bilinear (as
// scene::Environment::radiance looks maps up): linear between consecutive row centres
// theta_v = pi (v + 1/2)/H, clamped to the first and last row above the first and below the last centre.
std::vector<Piece> theta_pieces(int height, LatLongFilter filter) {
  std::vector<Piece> pieces;
  const double dt = kPi / height;
  if (filter == LatLongFilter::Nearest) {
    for (int v = 0; v < height; ++v) pieces.push_back({dt * v, dt * (v + 1), v, v, 0.0});
    return pieces;
  }
  pieces.push_back({0.0, 0.5 * dt, 0, 0, 0.0});
  for (int v = 0; v + 1 < height; ++v) pieces.push_back({dt * (v + 0.5), dt * (v + 1.5), v, v + 1, 1.0 / dt});
  pieces.push_back({kPi - 0.5 * dt, kPi, height - 1, height - 1, 0.0});
  return pieces;
}

}  // namespace

Vec3<double> latlong_direction(double u, double v, int width, int height) {
  double theta = kPi * (v + 0.5) / height;
  double phi = 2.0 * kPi * (u + 0.5) / width;
  double st = std::sin(theta);
  return {st * std::cos(phi), std::cos(theta), -st * std::sin(phi)};
}

std::vector<double> project_latlong(int order, const float* pixels, int width, int height, int channels,
                                    LatLongFilter filter) {
  check_order(order, "project_latlong");
  if (width < 1 || height < 1 || width > 65536 || height > 65536 || channels < 1 || channels > 4 || pixels == nullptr) {
    std::ostringstream os;
    os << "project_latlong: image size " << width << "x" << height << "x" << channels << " is not a valid lat-long map";
    throw std::invalid_argument(os.str());
  }
  const std::size_t n_values = static_cast<std::size_t>(width) * height * channels;
  for (std::size_t k = 0; k < n_values; ++k) {
    if (!std::isfinite(pixels[k])) {
      const std::size_t px = k / static_cast<std::size_t>(channels);
      std::ostringstream os;
      os << "project_latlong: pixel (" << px % static_cast<std::size_t>(width) << ", " << px / static_cast<std::size_t>(width)
         << ") channel " << k % static_cast<std::size_t>(channels) << " is " << pixels[k];
      throw std::invalid_argument(os.str());
    }
  }
  const int n2 = num_coeffs(order);
  const std::size_t C = static_cast<std::size_t>(channels);

  // phi kernels of column u, centre phi_u = (u + 1/2) dphi: box of width dphi, or the hat of half-width
  // dphi that the bilinear lookup's wrap in u periodises (the hats sum to 1 for every W >= 1). Their
  // Fourier integrals: int b_u cos(m phi) = dphi K_m cos(m phi_u), sin alike, with K_m = sinc(m dphi/2)
  // (box) or sinc^2(m dphi/2) (hat), exact.
  const double dphi = 2.0 * kPi / width;
  // rows[((v * order + m) * 2 + s) * C + c]: sum_u pixel * int b_u (s = 0: cos, 1: sin)(m phi) dphi.
  std::vector<double> rows(static_cast<std::size_t>(height) * order * 2 * C, 0.0);
  std::vector<double> cw(static_cast<std::size_t>(order) * width), sw(cw.size());
  for (int m = 0; m < order; ++m) {
    const double s = sinc(0.5 * m * dphi);
    const double k = dphi * (filter == LatLongFilter::Nearest ? s : s * s);
    for (int u = 0; u < width; ++u) {
      const double phi = dphi * (u + 0.5);
      cw[static_cast<std::size_t>(m) * width + u] = k * std::cos(m * phi);
      sw[static_cast<std::size_t>(m) * width + u] = k * std::sin(m * phi);
    }
  }
  for (int v = 0; v < height; ++v) {
    for (int m = 0; m < order; ++m) {
      double* r = rows.data() + (static_cast<std::size_t>(v) * order + m) * 2 * C;
      const double* cm = cw.data() + static_cast<std::size_t>(m) * width;
      const double* sm = sw.data() + static_cast<std::size_t>(m) * width;
      for (int u = 0; u < width; ++u) {
        const float* px = pixels + (static_cast<std::size_t>(v) * width + u) * C;
        for (std::size_t c = 0; c < C; ++c) {
          r[c] += px[c] * cm[u];
          r[C + c] += px[c] * sm[u];
        }
      }
    }
  }

  // theta integrals. A_lm(theta) sin(theta) is a trigonometric polynomial of degree <= order, times
  // the reconstruction's linear weight on each piece. Panels of length h <= pi / (2 k), k = order + 1,
  // with 8 Gauss-Legendre nodes: the error bound h^17 (8!)^4 / (17 (16!)^3) max|f^(16)|, with
  // max|f^(16)| <= (k^16 + 16 k^15 / h) max|f| by Bernstein's inequality for the trigonometric factor
  // and Leibniz's rule for the linear one, is below 1e-19 max|f|: exact in double.
  constexpr int kNodes = 8;
  const GaussLegendre& gl = gauss_legendre(kNodes);
  const double max_panel = kPi / (2.0 * (order + 1));
  // The frame p = P d puts the map's theta, phi in the standard position; A_lm for m >= 0 is y_lm at
  // phi = 0 and for m < 0 it is y_lm at phi = pi / (2|m|), where sin(|m| phi) = 1.
  std::vector<double> g(C * n2, 0.0);
  std::array<double, kMaxCoeffs> y{}, amp{};
  for (const Piece& pc : theta_pieces(height, filter)) {
    const int panels = std::max(1, static_cast<int>(std::ceil((pc.b - pc.a) / max_panel)));
    const double h = (pc.b - pc.a) / panels;
    for (int q = 0; q < panels; ++q) {
      for (int k = 0; k < kNodes; ++k) {
        const double theta = pc.a + h * (q + 0.5 * (gl.nodes[k] + 1.0));
        const double st = std::sin(theta), ct = std::cos(theta);
        const double w = 0.5 * h * gl.weights[k] * st;
        const double t = pc.slope * (theta - pc.a);
        eval_basis(order, Vec3<double>{st, 0.0, ct}, y.data());
        for (int l = 0; l < order; ++l)
          for (int m = 0; m <= l; ++m) amp[index(l, m)] = y[index(l, m)];
        for (int m = 1; m < order; ++m) {
          const double phi = 0.5 * kPi / m;
          eval_basis(order, Vec3<double>{st * std::cos(phi), st * std::sin(phi), ct}, y.data());
          for (int l = m; l < order; ++l) amp[index(l, -m)] = y[index(l, -m)];
        }
        const double* r0 = rows.data() + static_cast<std::size_t>(pc.v0) * order * 2 * C;
        const double* r1 = rows.data() + static_cast<std::size_t>(pc.v1) * order * 2 * C;
        for (int l = 0; l < order; ++l) {
          for (int m = -l; m <= l; ++m) {
            const int i = index(l, m);
            const std::size_t off = (static_cast<std::size_t>(std::abs(m)) * 2 + (m < 0 ? 1 : 0)) * C;
            const double wa = w * amp[i];
            for (std::size_t c = 0; c < C; ++c) g[c * n2 + i] += wa * ((1.0 - t) * r0[off + c] + t * r1[off + c]);
          }
        }
      }
    }
  }

  // f(d) = g(P d) with P: d -> (d.x, -d.z, d.y); ShRotation(R) gives f'(s) = f(R^T s), so f is g
  // turned by R = P^T.
  const Mat3 p_transpose = {{{1.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, {0.0, -1.0, 0.0}}};
  const ShRotation rot(order, p_transpose);
  std::vector<double> out(C * n2);
  for (std::size_t c = 0; c < C; ++c) rot.apply(g.data() + c * n2, out.data() + c * n2);
  return out;
}

}  // namespace softgi::sh
