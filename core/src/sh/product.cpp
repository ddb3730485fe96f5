#include "softgi/sh/product.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "softgi/sh/quadrature.hpp"

namespace softgi::sh {

TripleProduct::TripleProduct(int order) : order_(order) {
  check_order(order, "TripleProduct");
  const int n2 = num_coeffs(order);
  // The integrand y_i y_j y_k has degree <= 3(n-1): a product rule with B bands integrates degree
  // < 2B exactly, so B = ceil((3(n-1)+1)/2) + 1 nodes make every entry exact up to rounding.
  const int bands = (3 * (order - 1) + 1) / 2 + 2;
  const SphereQuadrature q = make_sphere_quadrature(bands);
  std::vector<std::array<double, kMaxCoeffs>> y(q.dirs.size());
  for (std::size_t s = 0; s < q.dirs.size(); ++s) eval_basis(order, q.dirs[s], y[s].data());

  for (int i = 0; i < n2; ++i) {
    for (int j = i; j < n2; ++j) {
      for (int k = j; k < n2; ++k) {
        // Selection rule |l_i - l_j| <= l_k <= l_i + l_j with even sum: skip early (pure speed).
        int li = band_of(i), lj = band_of(j), lk = band_of(k);
        if (lk > li + lj || lk < std::abs(li - lj) || ((li + lj + lk) & 1)) continue;
        double v = 0.0;
        for (std::size_t s = 0; s < q.dirs.size(); ++s) v += q.weights[s] * y[s][i] * y[s][j] * y[s][k];
        if (std::abs(v) <= kTripleZero) continue;
        unique_.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(j), static_cast<std::uint8_t>(k), v});
        // Ordered permutations of (i, j, k): 1, 3 or 6 distinct.
        ordered_nonzeros_ += (i == j && j == k) ? 1 : (i == j || j == k) ? 3 : 6;
      }
    }
  }
  for (int i = 0; i < n2; ++i)
    for (int j = 0; j < n2; ++j)
      for (int k = 0; k < n2; ++k) {
        int li = band_of(i), lj = band_of(j), lk = band_of(k);
        if (lk > li + lj || lk < std::abs(li - lj) || ((li + lj + lk) & 1)) continue;
        int mi = i - li * li - li, mj = j - lj * lj - lj, mk = k - lk * lk - lk;
        int a = std::abs(mi), b = std::abs(mj), c = std::abs(mk);
        if (!(a == b + c || b == a + c || c == a + b)) continue;
        if (((mi < 0) + (mj < 0) + (mk < 0)) % 2) continue;
        ++structural_nonzeros_;
      }
  // Expand into per-output-index terms with j <= k: for every unique (a <= b <= c), each distinct
  // choice of output index among {a, b, c} gives one term.
  for (const Entry& e : unique_) {
    const int idx[3] = {e.i, e.j, e.k};
    for (int o = 0; o < 3; ++o) {
      if (o > 0 && idx[o] == idx[o - 1]) continue;  // same output index already emitted
      int r0 = idx[(o + 1) % 3], r1 = idx[(o + 2) % 3];
      if (r0 > r1) std::swap(r0, r1);
      Term t{static_cast<std::uint8_t>(idx[o]), static_cast<std::uint8_t>(r0), static_cast<std::uint8_t>(r1), e.value};
      product_terms_.push_back(t);
      Term sq = t;
      if (r0 != r1) sq.value *= 2.0;
      square_terms_.push_back(sq);
    }
  }
  // Terms sorted by output index, diagonal (j == k) terms after the off-diagonal ones of the same
  // output, so each output is one register accumulation with no branch (see product()).
  std::stable_sort(product_terms_.begin(), product_terms_.end(), [](const Term& a, const Term& b) {
    if (a.i != b.i) return a.i < b.i;
    return (a.j == a.k) < (b.j == b.k);
  });
  std::stable_sort(square_terms_.begin(), square_terms_.end(), [](const Term& a, const Term& b) { return a.i < b.i; });
  offdiag_end_.assign(n2, 0);
  term_begin_.assign(n2 + 1, 0);
  sq_begin_.assign(n2 + 1, 0);
  for (std::size_t t = 0; t < product_terms_.size(); ++t) {
    const Term& term = product_terms_[t];
    term_begin_[term.i + 1] = static_cast<std::uint32_t>(t + 1);
    if (term.j != term.k) offdiag_end_[term.i] = static_cast<std::uint32_t>(t + 1);
  }
  for (int i = 0; i < n2; ++i) {
    term_begin_[i + 1] = std::max(term_begin_[i + 1], term_begin_[i]);
    offdiag_end_[i] = std::max(offdiag_end_[i], term_begin_[i]);
  }
  for (std::size_t t = 0; t < square_terms_.size(); ++t) sq_begin_[square_terms_[t].i + 1] = static_cast<std::uint32_t>(t + 1);
  for (int i = 0; i < n2; ++i) sq_begin_[i + 1] = std::max(sq_begin_[i + 1], sq_begin_[i]);
  // j != k: f_j g_k (1), + f_k g_j (2), acc += v s (2); j == k: 1 + 2. Squares: 1 + 2 per term.
  for (const Term& t : product_terms_) product_flops_ += t.j != t.k ? 5 : 3;
  square_flops_ = 3 * square_terms_.size();
  for (const Term& t : product_terms_) {
    product_values_d_.push_back(t.value);
    product_values_f_.push_back(static_cast<float>(t.value));
  }
  for (const Term& t : square_terms_) {
    square_values_d_.push_back(t.value);
    square_values_f_.push_back(static_cast<float>(t.value));
  }
}

const TripleProduct& TripleProduct::get(int order) {
  check_order(order, "TripleProduct::get");
  static std::mutex mutex;
  static std::array<std::unique_ptr<TripleProduct>, kMaxOrder + 1> cache;
  std::lock_guard<std::mutex> lock(mutex);
  if (!cache[order]) cache[order].reset(new TripleProduct(order));
  return *cache[order];
}

double TripleProduct::value(int i, int j, int k) const {
  int a = i, b = j, c = k;
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  for (const Entry& e : unique_)
    if (e.i == a && e.j == b && e.k == c) return e.value;
  return 0.0;
}

template <>
const double* TripleProduct::product_values<double>() const { return product_values_d_.data(); }
template <>
const float* TripleProduct::product_values<float>() const { return product_values_f_.data(); }
template <>
const double* TripleProduct::square_values<double>() const { return square_values_d_.data(); }
template <>
const float* TripleProduct::square_values<float>() const { return square_values_f_.data(); }

template <class T>
void TripleProduct::product(const T* f, const T* g, T* out) const {
  const int n2 = num_coeffs(order_);
  const T* v = product_values<T>();
  const Term* terms = product_terms_.data();
  for (int i = 0; i < n2; ++i) {
    T acc = 0;
    const std::uint32_t mid = offdiag_end_[i], end = term_begin_[i + 1];
    for (std::uint32_t t = term_begin_[i]; t < mid; ++t) acc += v[t] * (f[terms[t].j] * g[terms[t].k] + f[terms[t].k] * g[terms[t].j]);
    for (std::uint32_t t = mid; t < end; ++t) acc += v[t] * (f[terms[t].j] * g[terms[t].j]);
    out[i] = acc;
  }
}

template <class T>
void TripleProduct::square(const T* f, T* out) const {
  const int n2 = num_coeffs(order_);
  const T* v = square_values<T>();
  const Term* terms = square_terms_.data();
  for (int i = 0; i < n2; ++i) {
    T acc = 0;
    for (std::uint32_t t = sq_begin_[i]; t < sq_begin_[i + 1]; ++t) acc += v[t] * (f[terms[t].j] * f[terms[t].k]);
    out[i] = acc;
  }
}

template <class T>
void TripleProduct::product_matrix(const T* f, T* out) const {
  const int n2 = num_coeffs(order_);
  for (int i = 0; i < n2 * n2; ++i) out[i] = 0;
  // (M_f)_ij = sum_k Gamma_ijk f_k: every ordered (i, j) pair of each unique entry.
  for (const Entry& e : unique_) {
    const int idx[3] = {e.i, e.j, e.k};
    // all 6 permutations (p, q, r); duplicates when indices coincide are skipped
    static constexpr int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    int done[6][3];
    int ndone = 0;
    for (const auto& p : perm) {
      int a = idx[p[0]], b = idx[p[1]], c = idx[p[2]];
      bool dup = false;
      for (int d = 0; d < ndone; ++d)
        if (done[d][0] == a && done[d][1] == b && done[d][2] == c) dup = true;
      if (dup) continue;
      done[ndone][0] = a;
      done[ndone][1] = b;
      done[ndone][2] = c;
      ++ndone;
      out[a * n2 + b] += static_cast<T>(e.value) * f[c];
    }
  }
}

template <class T>
T TripleProduct::triple_integral(const T* a, const T* b, const T* c) const {
  std::array<T, kMaxCoeffs> ab{};
  product(a, b, ab.data());
  T s = 0;
  for (int i = 0; i < num_coeffs(order_); ++i) s += ab[i] * c[i];
  return s;
}

template void TripleProduct::product<float>(const float*, const float*, float*) const;
template void TripleProduct::product<double>(const double*, const double*, double*) const;
template void TripleProduct::square<float>(const float*, float*) const;
template void TripleProduct::square<double>(const double*, double*) const;
template void TripleProduct::product_matrix<float>(const float*, float*) const;
template void TripleProduct::product_matrix<double>(const double*, double*) const;
template float TripleProduct::triple_integral<float>(const float*, const float*, const float*) const;
template double TripleProduct::triple_integral<double>(const double*, const double*, const double*) const;

template <class T>
std::vector<T> product(int order, std::span<const T> f, std::span<const T> g) {
  check_order(order, "sh::product");
  check_size(f, order, "sh::product (f)");
  check_size(g, order, "sh::product (g)");
  std::vector<T> out(num_coeffs(order));
  TripleProduct::get(order).product(f.data(), g.data(), out.data());
  return out;
}
template <class T>
std::vector<T> square(int order, std::span<const T> f) {
  check_order(order, "sh::square");
  check_size(f, order, "sh::square");
  std::vector<T> out(num_coeffs(order));
  TripleProduct::get(order).square(f.data(), out.data());
  return out;
}
template std::vector<float> product<float>(int, std::span<const float>, std::span<const float>);
template std::vector<double> product<double>(int, std::span<const double>, std::span<const double>);
template std::vector<float> square<float>(int, std::span<const float>);
template std::vector<double> square<double>(int, std::span<const double>);

}  // namespace softgi::sh
