// SHEXP's product-space baseline (paper 004 eq. 6) and the projected reference.
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

#include "shexp_internal.hpp"
#include "softgi/sh/product.hpp"


namespace softgi::techniques::shexp {
// ---------------------------------------------------------------------------------------------

// ---------------------------------------------------------------------------------------------

// ---------------------------------------------------------------------------------------------

long long accumulate_product(const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                             std::size_t end, const BlockerList& blockers, float* out) {
  const int n = vis_table.order;
  const int n2 = n * n;
  const sh::TripleProduct& tp = sh::TripleProduct::get(n);
  // The same flush-to-zero as the log-space kernels (kernel.cpp), so that neither side of the
  // product-vs-log comparison pays for subnormal arithmetic.
  const unsigned csr = _mm_getcsr();
  _mm_setcsr(csr | 0x8040u);
  struct Restore {
    unsigned v;
    ~Restore() { _mm_setcsr(v); }
  } restore{csr};
  long long products = 0;
  std::array<float, sh::kMaxCoeffs> acc{}, g{}, tmp{};
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nn(rec.nx[i], rec.ny[i], rec.nz[i]);
    std::fill(acc.begin(), acc.begin() + n2, 0.0f);
    acc[0] = static_cast<float>(sh::kSqrt4Pi);  // the constant 1
    for (std::size_t b = 0; b < blockers.size(); ++b) {
      const AdjustedSphere s = apply_replacement_rule(rule, p, nn, glm::vec3(blockers.cx[b], blockers.cy[b], blockers.cz[b]),
                                                      blockers.r[b]);
      if (!(s.radius > 0.0f)) continue;  // eliminated: visibility 1 changes nothing
      sphere_zh_vector(vis_table, p, s.center, s.radius, nullptr, g.data());
      tp.product(acc.data(), g.data(), tmp.data());
      std::copy(tmp.begin(), tmp.begin() + n2, acc.begin());
      ++products;
    }
    std::copy(acc.begin(), acc.begin() + n2, out + i * n2);
  }
  return products;
}

void project_visibility(int order, int bands, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                        std::size_t end, const BlockerList& blockers, float* out) {
  const int n2 = order * order;
  static thread_local std::map<int, std::pair<sh::SphereQuadrature, std::vector<float>>> cache;
  auto& entry = cache[bands * 16 + order];
  if (entry.first.dirs.empty()) {
    entry.first = sh::make_sphere_quadrature(bands);
    entry.second.resize(entry.first.dirs.size() * n2);
    for (std::size_t k = 0; k < entry.first.dirs.size(); ++k) {
      std::array<double, sh::kMaxCoeffs> y{};
      sh::eval_basis(order, entry.first.dirs[k], y.data());
      for (int i = 0; i < n2; ++i) entry.second[k * n2 + i] = static_cast<float>(y[i] * entry.first.weights[k]);
    }
  }
  const sh::SphereQuadrature& q = entry.first;
  std::vector<AdjustedSphere> adj;
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nn(rec.nx[i], rec.ny[i], rec.nz[i]);
    adj.clear();
    for (std::size_t b = 0; b < blockers.size(); ++b) {
      AdjustedSphere s = apply_replacement_rule(rule, p, nn, glm::vec3(blockers.cx[b], blockers.cy[b], blockers.cz[b]), blockers.r[b]);
      if (s.radius > 0.0f) adj.push_back(s);
    }
    float* g = out + i * n2;
    std::fill(g, g + n2, 0.0f);
    for (std::size_t k = 0; k < q.dirs.size(); ++k) {
      const glm::vec3 d(static_cast<float>(q.dirs[k].x), static_cast<float>(q.dirs[k].y), static_cast<float>(q.dirs[k].z));
      bool blocked = false;
      for (const auto& s : adj) {
        // The ray p + t d (t > 0) meets the sphere: the cone of directions within its angular radius.
        const glm::vec3 c = s.center - p;
        const float dist2 = glm::dot(c, c), r2 = s.radius * s.radius;
        const float cd = glm::dot(c, d);
        if (dist2 <= r2 || (cd > 0.0f && dist2 - cd * cd <= r2)) {
          blocked = true;
          break;
        }
      }
      if (blocked) continue;
      const float* y = entry.second.data() + k * n2;
      for (int j = 0; j < n2; ++j) g[j] += y[j];
    }
  }
}

}  // namespace softgi::techniques::shexp
