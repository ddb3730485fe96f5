// ProductPlan: the triple-product tensor of sh::TripleProduct grouped by output index (paper 004
// eq. 3), the terms every batched SH product and square walks. Its own translation unit, so that the
// build's generator of written-out products (gen/sh_plan_cpp.cpp) can be linked against it alone.
#include <algorithm>
#include <array>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "accumulation.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::common {

const ProductPlan& ProductPlan::get(int order) {
  if (order < 1 || order > kMaxAccOrder) throw std::invalid_argument("ProductPlan: order " + std::to_string(order) + " outside [1, 8]");
  static std::mutex m;
  static std::array<std::unique_ptr<ProductPlan>, kMaxAccOrder + 1> cache;
  std::lock_guard<std::mutex> lock(m);
  if (cache[order]) return *cache[order];
  auto p = std::make_unique<ProductPlan>();
  p->order = order;
  const int n2 = order * order;
  struct Term {
    int i, j, k;
    double v;
  };
  std::vector<Term> prod;
  // Every unique (a <= b <= c) entry gives one term per distinct output index (as sh::TripleProduct).
  for (const auto& e : sh::TripleProduct::get(order).unique_entries()) {
    const int idx[3] = {e.i, e.j, e.k};
    for (int o = 0; o < 3; ++o) {
      if (o > 0 && idx[o] == idx[o - 1]) continue;
      int r0 = idx[(o + 1) % 3], r1 = idx[(o + 2) % 3];
      if (r0 > r1) std::swap(r0, r1);
      prod.push_back({idx[o], r0, r1, e.value});
    }
  }
  std::stable_sort(prod.begin(), prod.end(), [](const Term& a, const Term& b) {
    if (a.i != b.i) return a.i < b.i;
    return (a.j == a.k) < (b.j == b.k);
  });
  p->pr_begin.assign(n2 + 1, 0);
  p->pr_offdiag_end.assign(n2, 0);
  p->sq_begin.assign(n2 + 1, 0);
  for (const Term& t : prod) {
    p->pr_j.push_back(static_cast<std::uint16_t>(t.j));
    p->pr_k.push_back(static_cast<std::uint16_t>(t.k));
    p->pr_v.push_back(static_cast<float>(t.v));
    p->sq_j.push_back(static_cast<std::uint16_t>(t.j));
    p->sq_k.push_back(static_cast<std::uint16_t>(t.k));
    p->sq_v.push_back(static_cast<float>(t.j != t.k ? 2.0 * t.v : t.v));
    ++p->pr_begin[t.i + 1];
    if (t.j != t.k) ++p->pr_offdiag_end[t.i];
  }
  for (int i = 0; i < n2; ++i) {
    p->pr_begin[i + 1] += p->pr_begin[i];
    p->pr_offdiag_end[i] += p->pr_begin[i];
  }
  p->sq_begin = p->pr_begin;
  cache[order] = std::move(p);
  return *cache[order];
}

}  // namespace softgi::techniques::common
