// General SH rotation (needed by paper 000 eq. 17 and paper 001 section 7.1).
#pragma once

#include <array>
#include <vector>

#include "softgi/sh/sh.hpp"

namespace softgi::sh {

// 3x3 rotation, row-major: r[row][col]; it maps direction s to R s.
using Mat3 = std::array<std::array<double, 3>, 3>;

Mat3 rotation_from_axis_angle(const Vec3<double>& axis, double angle);
// A rotation taking unit vector `from` onto unit vector `to` (shortest arc; any valid one when opposite).
Mat3 rotation_between(const Vec3<double>& from, const Vec3<double>& to);
Mat3 multiply(const Mat3& a, const Mat3& b);
Mat3 transpose(const Mat3& a);

// Block-diagonal SH rotation matrix for a 3x3 rotation R, bands 0..order-1, such that the
// coefficients f' = rotate(f) reconstruct f'(s) = f(R^T s): the function turned by R.
// Computed with the Ivanic-Ruedenberg recurrence (J. Phys. Chem. 1996, with the 1998 errata).
class ShRotation {
 public:
  ShRotation(int order, const Mat3& r);
  int order() const { return order_; }
  // Band-l block, (2l+1)^2 row-major, rows/cols indexed by m + l.
  const double* band(int l) const { return blocks_.data() + offsets_[l]; }
  double element(int l, int m_row, int m_col) const {
    return band(l)[(m_row + l) * (2 * l + 1) + (m_col + l)];
  }
  template <class T>
  void apply(const T* f, T* out) const;  // out must not alias f
  // Full n^2 x n^2 matrix, row-major (zeros off the band blocks).
  std::vector<double> dense() const;

 private:
  int order_;
  std::vector<double> blocks_;
  std::array<int, kMaxOrder + 1> offsets_{};
};

// Slow reference: each band block fitted from basis values at 2l+1 fixed directions,
// y_l(R^T s_k) = A_l y_l(s_k) -> block = A_l^T. For tests.
std::vector<double> rotation_reference_dense(int order, const Mat3& r);

}  // namespace softgi::sh
