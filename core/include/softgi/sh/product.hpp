// SH products through the triple-product tensor (paper 004 eqs. 3-5).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "softgi/sh/sh.hpp"

namespace softgi::sh {

// Gamma_ijk = int y_i y_j y_k ds, computed once per order by a quadrature that is exact for the
// degree-3(n-1) integrand, and stored sparse. Entries below kTripleZero in magnitude are exact zeros
// (selection rules) that the quadrature returns as rounding noise.
class TripleProduct {
 public:
  static constexpr double kTripleZero = 1e-12;

  struct Entry {
    std::uint8_t i, j, k;  // i <= j <= k
    double value;
  };
  struct Term {  // (f*g)_i += weight * (f_j g_k + f_k g_j [j != k]) ; square: weight*mult * f_j f_k
    std::uint8_t i, j, k;
    double value;
  };

  // Cached, thread-safe construction.
  static const TripleProduct& get(int order);

  int order() const { return order_; }
  // Numerically nonzero entries among all ordered (i, j, k).
  std::size_t nonzeros_ordered() const { return ordered_nonzeros_; }
  // Ordered entries allowed by the selection rules (band triangle, even band sum, real-basis m rules:
  // one |m| is the sum of the other two, and an even number of negative m). Paper 004's table
  // matches this count; it includes "accidental" zeros where two complex Gaunt terms cancel.
  std::size_t nonzeros_structural() const { return structural_nonzeros_; }
  // Nonzero entries with i <= j <= k: what is stored.
  std::size_t nonzeros_unique() const { return unique_.size(); }
  const std::vector<Entry>& unique_entries() const { return unique_; }
  // Gamma_ijk for any index order (linear search in a per-i list; for tests and tools).
  double value(int i, int j, int k) const;

  // (f*g)_i = sum_jk Gamma_ijk f_j g_k (eq. 3). out must not alias f or g.
  template <class T>
  void product(const T* f, const T* g, T* out) const;
  // f*f, cheaper than a general product (symmetric terms merged).
  template <class T>
  void square(const T* f, T* out) const;
  // (M_f)_ij = sum_k Gamma_ijk f_k (eq. 5), row-major n^2 x n^2.
  template <class T>
  void product_matrix(const T* f, T* out) const;
  // (a, b, c) = sum_ijk Gamma_ijk a_i b_j c_k: the integral of the product of three reconstructions.
  template <class T>
  T triple_integral(const T* a, const T* b, const T* c) const;

  // Floating-point operations of one product / one square (multiply-adds count 2).
  std::size_t product_flops() const { return product_flops_; }
  std::size_t square_flops() const { return square_flops_; }

 private:
  explicit TripleProduct(int order);
  int order_;
  std::size_t ordered_nonzeros_ = 0;
  std::size_t structural_nonzeros_ = 0;
  std::size_t product_flops_ = 0, square_flops_ = 0;
  std::vector<Entry> unique_;
  // For products: every (i, j<=k) with i free, value Gamma_ijk; the j != k terms add both f_j g_k + f_k g_j.
  std::vector<Term> product_terms_;
  std::vector<float> product_values_f_;
  // For squares: every (i, j<=k), value multiplied by 2 when j != k.
  std::vector<Term> square_terms_;
  // Per output index i: product terms [term_begin_[i], offdiag_end_[i]) have j != k, the rest of
  // [.., term_begin_[i+1]) have j == k; square terms [sq_begin_[i], sq_begin_[i+1]).
  std::vector<std::uint32_t> term_begin_, offdiag_end_, sq_begin_;
  std::vector<float> square_values_f_;
  template <class T>
  const T* product_values() const;
  template <class T>
  const T* square_values() const;
  std::vector<double> product_values_d_, square_values_d_;
};

// Convenience wrappers with size checks.
template <class T>
std::vector<T> product(int order, std::span<const T> f, std::span<const T> g);
template <class T>
std::vector<T> square(int order, std::span<const T> f);

}  // namespace softgi::sh
