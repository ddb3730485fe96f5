// Paper 001 section 6.1: the average-radiance weight (eqs. 16-18).
#include "sl_tables.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::techniques::spherical_lights {

namespace {
constexpr double kHalfPi = 0.5 * sh::kPi;
}

double cos_gamma(double theta, double alpha) {
  // Eq. 17 simplified: sin(atan((1 - s cos a)/(s sin a)) - a) = (cos a - s)/sqrt((1 - s cos a)^2 + (s sin a)^2),
  // with s = sin theta; the sum of squares has no cancellation and the atan's 0/0 at alpha = 0 is gone.
  const double s = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  const double num = ca - s;
  if (!(num > 0.0)) return 0.0;  // back-facing from p (the max(0, .) of eqs. 16-17)
  const double a = 1.0 - s * ca, b = s * sa;
  return std::min(1.0, num / std::sqrt(a * a + b * b));
}

std::vector<double> weight_zh(int order, double theta) {
  sh::check_order(order, "spherical_lights::weight_zh");
  if (!std::isfinite(theta) || theta < 0.0 || theta > kHalfPi + 1e-12)
    throw std::invalid_argument("spherical_lights::weight_zh: theta " + std::to_string(theta) +
                                " outside [0, pi/2]");
  theta = std::min(theta, kHalfPi);
  const double s = std::sin(theta), c = std::cos(theta);
  std::vector<double> out(order, 0.0);
  std::array<double, sh::kMaxCoeffs> y{};
  if (s == 0.0) {  // a point light's view: the clamped cosine max(0, cos alpha)/pi
    const std::vector<double> cc = sh::clamped_cosine_zh(order);
    for (int l = 0; l < order; ++l) out[l] = cc[l] / sh::kPi;
    return out;
  }
  // With mu = cos alpha the integrand of eq. 16 is f(mu) = (mu - s)/v on mu in [s, 1], v = sqrt(1 - 2 s mu + s^2).
  // Substituting v: mu = (1 + s^2 - v^2)/(2s), f dmu = (1 - s^2 - v^2)/(2 s^2) dv on v in [1 - s, cos theta],
  // a polynomial of degree 2 + 2l in v against y_l0(mu(v)): Gauss-Legendre with 16 nodes is exact for
  // every order <= 8. The 2 pi of the phi integral cancels in the normalisation.
  const double one_minus_s = c * c / (1.0 + s);     // 1 - sin theta without cancellation
  const double width = c - one_minus_s;             // length of the v interval
  if (!(width > 0.0)) {  // theta = pi/2: the weight is a delta at alpha = 0
    sh::eval_basis(order, sh::Vec3<double>{0.0, 0.0, 1.0}, y.data());
    for (int l = 0; l < order; ++l) out[l] = y[sh::index(l, 0)];
    return out;
  }
  const sh::GaussLegendre& gl = sh::gauss_legendre(16);
  double den = 0.0;
  for (std::size_t k = 0; k < gl.nodes.size(); ++k) {
    const double t = 0.5 * (gl.nodes[k] + 1.0);
    const double v = one_minus_s + t * width;
    const double omv = s - t * width;                  // 1 - v
    const double one_minus_v2 = omv * (2.0 - omv);     // 1 - v^2
    // 1 - s^2 - v^2 = (cos theta - v)(cos theta + v): no cancellation near theta = pi/2.
    const double g = (1.0 - t) * width * (c + v) / (2.0 * s * s);
    const double mu = std::clamp((one_minus_v2 + s * s) / (2.0 * s), -1.0, 1.0);
    const double wk = 0.5 * width * gl.weights[k] * g;
    sh::eval_basis(order, sh::Vec3<double>{std::sqrt(std::max(0.0, 1.0 - mu * mu)), 0.0, mu}, y.data());
    den += wk;
    for (int l = 0; l < order; ++l) out[l] += wk * y[sh::index(l, 0)];
  }
  for (int l = 0; l < order; ++l) out[l] /= den;  // eq. 16's normalisation
  return out;
}

void WeightTable::lookup(float theta, float* out_w) const {
  if (!(theta > 0.0f)) theta = 0.0f;  // also NaN
  const float x = std::min(theta, static_cast<float>(kHalfPi)) * static_cast<float>((rows - 1) / kHalfPi);
  const int k = std::min(static_cast<int>(x), rows - 2);
  const float f = std::min(1.0f, x - static_cast<float>(k));
  const float* a = w.data() + static_cast<std::size_t>(k) * order;
  const float* b = a + order;
  for (int l = 0; l < order; ++l) out_w[l] = a[l] + f * (b[l] - a[l]);
}

WeightTable make_weight_table(int order, int rows) {
  sh::check_order(order, "spherical_lights::make_weight_table");
  if (rows < 2)
    throw std::invalid_argument("spherical_lights::make_weight_table: rows " + std::to_string(rows) + " < 2");
  WeightTable t;
  t.order = order;
  t.rows = rows;
  t.w.resize(static_cast<std::size_t>(rows) * order);
  for (int k = 0; k < rows; ++k) {
    const std::vector<double> zh = weight_zh(order, k == rows - 1 ? kHalfPi : k * kHalfPi / (rows - 1));
    for (int l = 0; l < order; ++l) t.w[static_cast<std::size_t>(k) * order + l] = static_cast<float>(zh[l]);
  }
  return t;
}

float average_radiance(const WeightTable& t, const float* L, const glm::vec3& dir_local, float theta) {
  std::array<float, sh::kMaxOrder> w{};
  std::array<float, sh::kMaxCoeffs> y{};
  t.lookup(theta, w.data());
  sh::eval_basis(t.order, sh::Vec3<float>{dir_local.x, dir_local.y, dir_local.z}, y.data());
  // Eq. 18 with the ZH rotation rule: f_lm = sqrt(4 pi/(2l+1)) w_l y_lm(dir).
  float sum = 0.0f;
  for (int l = 0; l < t.order; ++l) {
    float band = 0.0f;
    for (int m = -l; m <= l; ++m) band += y[sh::index(l, m)] * L[sh::index(l, m)];
    sum += static_cast<float>(sh::zh_rotation_factor(l)) * w[l] * band;
  }
  return sum;
}

}  // namespace softgi::techniques::spherical_lights
