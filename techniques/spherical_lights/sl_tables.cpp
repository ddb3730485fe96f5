// Paper 001 section 6.1: the average-radiance weight (eqs. 16-18).
#include "sl_tables.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "softgi/sh/tables.hpp"
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
  // The SH core's one definition (softgi/sh/tables.hpp, derivation in docs/sh_indirect_tables.md).
  return sh::spherical_light_weight_zh(order, std::sin(std::min(theta, kHalfPi)));
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

WeightTable weight_table_from(const sh::Table1D& table, int order) {
  if (table.param != sh::TableParam::Theta || table.width < order || table.rows() < 2)
    throw std::invalid_argument("spherical_lights::weight_table_from: needs a theta-sampled table of width >= " + std::to_string(order));
  WeightTable t;
  t.order = order;
  t.rows = table.rows();
  t.w.resize(static_cast<std::size_t>(t.rows) * order);
  for (int k = 0; k < t.rows; ++k)
    for (int l = 0; l < order; ++l) t.w[static_cast<std::size_t>(k) * order + l] = static_cast<float>(table.row(k)[l]);
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
