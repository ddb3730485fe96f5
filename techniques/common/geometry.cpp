// Geometry of the shared accumulation library: the replacement rules (paper 004 section 6.2),
// ZH tables and single-sphere vectors (eq. 34), receiver and blocker structure-of-arrays.
#include <xmmintrin.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "accumulation.hpp"
#include "softgi/sh/product.hpp"


namespace softgi::techniques::common {

const char* to_string(ReplacementRule r) {
  switch (r) {
    case ReplacementRule::Off: return "off";
    case ReplacementRule::Continuous: return "continuous";
    case ReplacementRule::Clamped: return "clamped";
    case ReplacementRule::Printed: return "printed";
    case ReplacementRule::InsideOnly: return "inside_only";
  }
  return "?";
}

ReplacementRule parse_replacement_rule(const std::string& s) {
  if (s == "off") return ReplacementRule::Off;
  if (s == "continuous") return ReplacementRule::Continuous;
  if (s == "clamped") return ReplacementRule::Clamped;
  if (s == "printed") return ReplacementRule::Printed;
  if (s == "inside_only") return ReplacementRule::InsideOnly;
  throw std::invalid_argument("unknown replacement rule '" + s + "' (expected off, continuous, clamped, printed or inside_only)");
}

// ---------------------------------------------------------------------------------------------

ZhTable make_zh_table(const sh::Table1D& table, int order, bool zero_first_row) {
  if (table.param != sh::TableParam::Theta)
    throw std::invalid_argument("ZH tables must be sampled uniformly in theta");
  if (table.width < order) throw std::invalid_argument("ZH table narrower than the order");
  if (table.rows() < 2) throw std::invalid_argument("ZH table with fewer than 2 rows");
  ZhTable t;
  t.order = order;
  t.rows = table.rows();
  t.scale = static_cast<float>((t.rows - 1) / (table.x.back() - table.x.front()));
  t.data.assign(static_cast<std::size_t>(t.rows) * 2 * order, 0.0f);
  std::vector<double> vals(static_cast<std::size_t>(t.rows) * order);
  for (int k = 0; k < t.rows; ++k)
    for (int l = 0; l < order; ++l)
      vals[static_cast<std::size_t>(k) * order + l] =
          (zero_first_row && k == 0) ? 0.0 : table.row(k)[l] * sh::zh_rotation_factor(l);
  for (int k = 0; k < t.rows; ++k)
    for (int l = 0; l < order; ++l) {
      const double v = vals[static_cast<std::size_t>(k) * order + l];
      const double next = k + 1 < t.rows ? vals[static_cast<std::size_t>(k + 1) * order + l] : v;
      t.data[static_cast<std::size_t>(k) * 2 * order + 2 * l] = static_cast<float>(v);
      t.data[static_cast<std::size_t>(k) * 2 * order + 2 * l + 1] = static_cast<float>(next - v);
    }
  t.band.assign(t.data.size(), 0.0f);
  for (int l = 0; l < order; ++l)
    for (int k = 0; k < t.rows; ++k) {
      t.band[static_cast<std::size_t>(l) * 2 * t.rows + k] = t.data[static_cast<std::size_t>(k) * 2 * order + 2 * l];
      t.band[static_cast<std::size_t>(l) * 2 * t.rows + t.rows + k] = t.data[static_cast<std::size_t>(k) * 2 * order + 2 * l + 1];
    }
  return t;
}

void ZhTable::lookup(float theta, float* out) const {
  float u = theta * scale;
  if (!(u > 0.0f)) u = 0.0f;
  int k = std::min(static_cast<int>(std::min(u, static_cast<float>(rows - 1))), rows - 2);
  const float fr = u - static_cast<float>(k);
  const float* row = data.data() + static_cast<std::size_t>(k) * 2 * order;
  for (int l = 0; l < order; ++l) out[l] = row[2 * l] + fr * row[2 * l + 1];
}

void sphere_zh_vector(const ZhTable& table, const glm::vec3& p, const glm::vec3& c, float r, const float* w, float* out) {
  const int n = table.order;
  const glm::vec3 d = c - p;
  const float dist = glm::length(d);
  std::array<float, kMaxAccOrder> f{};
  const float theta = dist > 0.0f ? std::asin(std::min(1.0f, r / dist)) : static_cast<float>(sh::kPi / 2);
  table.lookup(theta, f.data());
  for (int l = 0; l < n; ++l) f[l] *= w ? w[l] : 1.0f;
  const glm::vec3 s = dist > 0.0f ? d / dist : glm::vec3(0.0f, 0.0f, 1.0f);
  std::array<float, sh::kMaxCoeffs> y{};
  sh::eval_basis(n, sh::Vec3<float>{s.x, s.y, s.z}, y.data());
  for (int l = 0; l < n; ++l)
    for (int m = -l; m <= l; ++m) out[sh::index(l, m)] = f[l] * y[sh::index(l, m)];
}

// ---------------------------------------------------------------------------------------------

void ReceiverSoA::resize(std::size_t n) {
  for (auto* v : {&px, &py, &pz, &nx, &ny, &nz}) v->assign(n, 0.0f);
}
void ReceiverSoA::set(std::size_t i, const glm::vec3& p, const glm::vec3& n) {
  px[i] = p.x;
  py[i] = p.y;
  pz[i] = p.z;
  nx[i] = n.x;
  ny[i] = n.y;
  nz[i] = n.z;
}

void BlockerList::push(const glm::vec3& c, float radius, const float* weights) {
  cx.push_back(c.x);
  cy.push_back(c.y);
  cz.push_back(c.z);
  r.push_back(radius);
  for (int l = 0; l < order; ++l) w.push_back(weights ? weights[l] : 1.0f);
}

}  // namespace softgi::techniques::common
