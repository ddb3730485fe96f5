// Analytic spherical lights for SHEXP (paper 004 section 7, "Analytic Lights"): a 2D table of
// L_H(theta, f) = L(theta, f) * H((0, 0, 1)), each entry fitted by a single-lobe ZH (Sloan et al.
// 2005) so that turning it to a receiver's frame is the ZH rotation rule of section 6.1.
#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include <tbb/parallel_for.h>

#include "accumulation.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::common {

namespace {
// Solid angle of a cone of half-angle theta, without cancellation for small theta.
double solid_angle(double theta) {
  const double s = std::sin(0.5 * theta);
  return 4.0 * sh::kPi * s * s;
}

struct LobeFit {
  double psi = 0.0;
  std::array<double, kMaxAccOrder> k{};
  double explained = 0.0;  // sum_l num_l^2 / den_l: energy of t captured by the lobe
};

// Best lobe about axis a(psi) = (sin psi, 0, cos psi): per band k_l = sum_m t_lm y_lm(a) / sum_m y_lm(a)^2.
LobeFit fit_at(int order, const std::vector<double>& t, double psi) {
  std::array<double, sh::kMaxCoeffs> y{};
  sh::eval_basis(order, sh::Vec3<double>{std::sin(psi), 0.0, std::cos(psi)}, y.data());
  LobeFit f;
  f.psi = psi;
  for (int l = 0; l < order; ++l) {
    double num = 0.0, den = 0.0;
    for (int m = -l; m <= l; ++m) {
      num += t[sh::index(l, m)] * y[sh::index(l, m)];
      den += y[sh::index(l, m)] * y[sh::index(l, m)];
    }
    f.k[l] = num / den;
    f.explained += num * num / den;
  }
  return f;
}

LobeFit fit_lobe(int order, const std::vector<double>& t) {
  // The canonical L_H is symmetric under y -> -y, so the lobe axis lies in the xz plane: a 1D search
  // over psi in [0, pi], coarse grid then golden-section refinement.
  constexpr int kGrid = 360;
  LobeFit best = fit_at(order, t, 0.0);
  for (int i = 1; i <= kGrid; ++i) {
    LobeFit f = fit_at(order, t, sh::kPi * i / kGrid);
    if (f.explained > best.explained) best = f;
  }
  double a = std::max(0.0, best.psi - sh::kPi / kGrid), b = std::min(sh::kPi, best.psi + sh::kPi / kGrid);
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int it = 0; it < 40; ++it) {
    double c = b - g * (b - a), d = a + g * (b - a);
    if (fit_at(order, t, c).explained > fit_at(order, t, d).explained) b = d;
    else a = c;
  }
  LobeFit refined = fit_at(order, t, 0.5 * (a + b));
  return refined.explained > best.explained ? refined : best;
}
}  // namespace

std::vector<double> light_lh_canonical(int order, double theta, double f, double window_h) {
  // Unit-radiance disc light: indicator of the cap of half-angle theta = 1 - cap visibility (eq. 33).
  std::vector<double> vis = sh::cap_visibility_zh(order, std::clamp(theta, 0.0, sh::kPi / 2));
  std::vector<double> ind(order);
  for (int l = 0; l < order; ++l) {
    ind[l] = (l == 0 ? sh::kSqrt4Pi : 0.0) - vis[l];
    if (window_h > 0.0) ind[l] *= sh::window_factor(l, window_h);
  }
  std::vector<double> L(sh::num_coeffs(order)), H(sh::num_coeffs(order)), out(sh::num_coeffs(order));
  sh::zh_rotate(order, ind.data(), sh::Vec3<double>{std::sin(f), 0.0, std::cos(f)}, L.data());
  sh::irradiance_weight(order, sh::Vec3<double>{0.0, 0.0, 1.0}, H.data());
  sh::TripleProduct::get(order).product(L.data(), H.data(), out.data());
  return out;
}

LightLobeTable make_light_lobe_table(int order, int rows_theta, int rows_f, double window_h) {
  if (order < 1 || order > kMaxAccOrder) throw std::invalid_argument("light lobe table: order " + std::to_string(order) + " outside [1, 8]");
  if (rows_theta < 2 || rows_f < 2 || rows_theta > 4096 || rows_f > 4096)
    throw std::invalid_argument("light lobe table: " + std::to_string(rows_theta) + " x " + std::to_string(rows_f) +
                                " samples outside [2, 4096]^2");
  LightLobeTable t;
  t.order = order;
  t.rows_theta = rows_theta;
  t.rows_f = rows_f;
  t.window_h = window_h;
  t.psi.assign(static_cast<std::size_t>(rows_theta) * rows_f, 0.0f);
  t.k.assign(static_cast<std::size_t>(rows_theta) * rows_f * order, 0.0f);
  std::vector<double> err(rows_theta, 0.0);
  tbb::parallel_for(0, rows_theta, [&](int i) {
    const double theta = std::max(kLightThetaFloor, (sh::kPi / 2) * i / (rows_theta - 1));
    const double omega = solid_angle(theta);
    double peak = 0.0, worst = 0.0;  // largest ||L_H|| and largest fit residual over f
    for (int j = 0; j < rows_f; ++j) {
      const double f = sh::kPi * j / (rows_f - 1);
      std::vector<double> lh = light_lh_canonical(order, theta, f, window_h);
      LobeFit fit = fit_lobe(order, lh);
      const std::size_t cell = static_cast<std::size_t>(i) * rows_f + j;
      t.psi[cell] = static_cast<float>(fit.psi);
      for (int l = 0; l < order; ++l) t.k[cell * order + l] = static_cast<float>(fit.k[l] / omega);
      double total = 0.0;
      for (double v : lh) total += v * v;
      peak = std::max(peak, std::sqrt(total));
      worst = std::max(worst, std::sqrt(std::max(0.0, total - fit.explained)));
    }
    err[i] = peak > 0.0 ? worst / peak : 0.0;
  });
  t.max_fit_error = *std::max_element(err.begin(), err.end());
  return t;
}

void LightLobeTable::lookup(float theta, float f, float& psi_out, float* k_out) const {
  lookup_unit(theta, f, psi_out, k_out);
  const float omega = static_cast<float>(solid_angle(std::max(static_cast<double>(theta), kLightThetaFloor)));
  for (int l = 0; l < order; ++l) k_out[l] *= omega;
}

void LightLobeTable::lookup_unit(float theta, float f, float& psi_out, float* k_out) const {
  auto coord = [](float x, float range, int rows, int& k0, float& w) {
    float u = x / range * static_cast<float>(rows - 1);
    if (!(u > 0.0f)) u = 0.0f;
    if (u > static_cast<float>(rows - 1)) u = static_cast<float>(rows - 1);
    k0 = std::min(static_cast<int>(u), rows - 2);
    w = u - static_cast<float>(k0);
  };
  int i0 = 0, j0 = 0;
  float wi = 0.0f, wj = 0.0f;
  coord(theta, static_cast<float>(sh::kPi / 2), rows_theta, i0, wi);
  coord(f, static_cast<float>(sh::kPi), rows_f, j0, wj);
  const float w[4] = {(1 - wi) * (1 - wj), (1 - wi) * wj, wi * (1 - wj), wi * wj};
  const std::size_t cells[4] = {static_cast<std::size_t>(i0) * rows_f + j0, static_cast<std::size_t>(i0) * rows_f + j0 + 1,
                                static_cast<std::size_t>(i0 + 1) * rows_f + j0, static_cast<std::size_t>(i0 + 1) * rows_f + j0 + 1};
  psi_out = 0.0f;
  for (int l = 0; l < order; ++l) k_out[l] = 0.0f;
  for (int c = 0; c < 4; ++c) {
    psi_out += w[c] * psi[cells[c]];
    for (int l = 0; l < order; ++l) k_out[l] += w[c] * k[cells[c] * order + l];
  }
}

bool light_lh_world(const LightLobeTable& t, const glm::vec3& p, const glm::vec3& n, const glm::vec3& c, float radius,
                    float* out) {
  const glm::vec3 d = c - p;
  const float dist = glm::length(d);
  if (!(dist > 0.0f) || !(radius > 0.0f)) return false;
  const float theta = dist > radius ? std::asin(radius / dist) : static_cast<float>(sh::kPi / 2);
  const glm::vec3 dir = d / dist;
  const float cf = std::clamp(glm::dot(dir, n), -1.0f, 1.0f);
  const float f = std::acos(cf);
  float psi = 0.0f;
  std::array<float, kMaxAccOrder> k{};
  t.lookup(theta, f, psi, k.data());
  // Canonical frame: N = z, light in the xz plane on the +x side; the lobe axis at psi from z.
  glm::vec3 tan = dir - cf * n;
  const float tl = glm::length(tan);
  if (tl > 1e-6f) {
    tan /= tl;
  } else {  // light on the normal: the lobe is on the normal too (psi = 0 or pi), any tangent will do
    tan = std::abs(n.x) < 0.9f ? glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))) : glm::normalize(glm::cross(n, glm::vec3(0, 1, 0)));
  }
  const glm::vec3 axis = std::cos(psi) * n + std::sin(psi) * tan;
  std::array<float, sh::kMaxCoeffs> y{};
  sh::eval_basis(t.order, sh::Vec3<float>{axis.x, axis.y, axis.z}, y.data());
  for (int l = 0; l < t.order; ++l)
    for (int m = -l; m <= l; ++m) out[sh::index(l, m)] = k[l] * y[sh::index(l, m)];
  return true;
}

long long add_lights_and_clamp(KernelIsa isa, const LightLobeTable* table, const std::vector<scene::SphericalLight>& lights,
                               int order, const float* gwin, const ReceiverSoA& rec, std::size_t begin, std::size_t end,
                               const float* g, bool zero_normal_empty, glm::vec3* out) {
  if (shades_lights(table, lights)) lights_batch(isa, *table, lights, order, gwin, rec, begin, end, g, out);
  long long clamped = 0;
  for (std::size_t i = begin; i < end; ++i) {
    if (zero_normal_empty && rec.nx[i] == 0.0f && rec.ny[i] == 0.0f && rec.nz[i] == 0.0f) {
      out[i - begin] = glm::vec3(0.0f);
      continue;
    }
    const glm::vec3 e = out[i - begin];
    // Truncated SH can ring below zero in deep shadow; outgoing radiance cannot.
    if (e.x < 0.0f || e.y < 0.0f || e.z < 0.0f) ++clamped;
    out[i - begin] = glm::max(e, glm::vec3(0.0f));
  }
  return clamped;
}

}  // namespace softgi::techniques::common
