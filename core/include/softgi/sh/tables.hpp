// Precomputed tables as functions of a spherical blocker's / proxy's angular radius theta
// (alpha = sin theta), built in double. Paper references: 004 section 6.1 and eq. 24;
// 000 section 3 and eqs. 14, 16; 001 eqs. 16-18.
#pragma once

#include <string>
#include <cstdint>
#include <vector>

#include "softgi/sh/sh.hpp"

namespace softgi::sh {

// --- Closed forms and references, per angular radius (all double) ------------------------------

// ZH of the visibility of a cap blocker of half-angle theta centred on +z (paper 004 eq. 33):
// 0 inside the cap, 1 outside. Closed form through Legendre polynomials.
std::vector<double> cap_visibility_zh(int order, double theta);
// ZH of the cap's log visibility: log_eigen (eqs. 30-32) of the cap visibility; the result of a
// ZH input stays zonal (M_g is block-diagonal in m), so only the m = 0 coefficients are kept.
std::vector<double> cap_log_zh(int order, double theta, double log_threshold = 0.02);

// Averaged indirect operator D(theta) of paper 000 eq. 14, bands 0..order-1 (ZH about +z).
// Computed by graded Gauss-Legendre quadrature of the canonical configuration, stable for
// alpha in [0, 1]. D(theta) . rot(., d) dotted with L~ gives the radiance averaged over the proxy disk.
std::vector<double> indirect_D_quadrature(int order, double alpha);
// The paper's order-3 closed form, rewritten without the catastrophic cancellation at alpha -> 0
// (d - d~ = tan(theta/2)). Bands 0..2.
std::array<double, 3> indirect_D_closed_form(double alpha);
// The closed form exactly as printed (d = csc theta, d~ = sqrt(d^2 - 1)), for comparison; it cancels
// catastrophically in float near alpha = 0. Evaluated in T.
template <class T>
std::array<T, 3> indirect_D_closed_form_as_printed(T alpha);
// The paper's polynomial fit (section 5): D0 = 0.28209, D1, D2 polynomials in alpha.
std::array<double, 3> indirect_D_polynomial(double alpha);
// Exact indirect operator M(theta) of paper 000 eq. 16: n^2 x n^2 row-major,
// M_jk = int v_theta(s) y_j(s) y_k(q^_theta(s)) ds. Block-diagonal in m.
std::vector<double> indirect_M(int order, double alpha);
// Spherical-light average-radiance weight w_theta of paper 001 eqs. 16-18, normalised to
// integrate to 1: ZH about the axis from the light's centre towards the receiver.
std::vector<double> spherical_light_weight_zh(int order, double alpha);

// --- Tables ------------------------------------------------------------------------------------

enum class TableParam { Theta, Alpha };  // samples uniform in theta (radians, 0..pi/2) or alpha (0..1)

// One table: `rows` samples of `width` doubles, linear interpolation between samples.
struct Table1D {
  TableParam param = TableParam::Theta;
  int width = 0;
  std::vector<double> x;     // sample positions (theta or alpha)
  std::vector<double> data;  // rows * width
  int rows() const { return static_cast<int>(x.size()); }
  const double* row(int k) const { return data.data() + static_cast<std::size_t>(k) * width; }
  // Interpolated row at parameter value xv (clamped to the table's range) into out[width].
  template <class T>
  void lookup(double xv, T* out) const;
  // Max abs difference between interpolated values at sample midpoints and exact values there.
  double max_interp_error = 0.0;
  double max_interp_error_at = 0.0;  // parameter value (theta or alpha) where it occurs
};

struct TableOptions {
  int order = 4;
  int resolution = 256;         // samples per table (paper 004 uses 256 in theta)
  TableParam param = TableParam::Theta;
  double log_threshold = 0.02;  // eigenvalue clip for cap logs (paper 004 section 5)
  bool measure_error = true;    // evaluate at midpoints to fill max_interp_error
  // The exact indirect operator M(theta) (paper 000 eq. 16) is n^4 doubles per sample (8 MB at
  // n = 8, 256 samples): built only when a technique asks for the exact operator.
  bool exact_indirect_operator = false;
};

class ShTables {
 public:
  explicit ShTables(const TableOptions& opt);
  const TableOptions& options() const { return opt_; }
  int order() const { return opt_.order; }

  const Table1D& cap_visibility() const { return cap_vis_; }  // width n
  const Table1D& cap_log() const { return cap_log_; }         // width n
  const Table1D& D_averaged() const { return d_avg_; }        // width n (quadrature)
  const Table1D& D_polynomial() const { return d_poly_; }     // width 3 (paper's fit)
  const Table1D& sl_weight() const { return sl_w_; }          // width n
  const Table1D& M_exact() const { return m_exact_; }         // width n^4 (empty unless requested)

  // OL (paper 004 eq. 24), per cap sample: ||f^||, a, b.
  const std::vector<double>& ol_norm() const { return ol_norm_; }
  const std::vector<double>& ol_a() const { return ol_a_; }
  const std::vector<double>& ol_b() const { return ol_b_; }
  // a(||f^||), b(||f^||) by linear interpolation over the monotone part of the sweep; clamped beyond.
  void ol_lookup(double norm, double& a, double& b) const;
  double ol_max_norm() const { return ol_norm_mono_.empty() ? 0.0 : ol_norm_mono_.back(); }
  double ol_interp_error() const { return ol_interp_error_; }

  // Bytes held by the tables (for the memory report).
  std::size_t bytes() const;

 private:
  TableOptions opt_;
  Table1D cap_vis_, cap_log_, d_avg_, d_poly_, sl_w_, m_exact_;
  std::vector<double> ol_norm_, ol_a_, ol_b_;
  std::vector<double> ol_norm_mono_, ol_a_mono_, ol_b_mono_;
  // Uniform buckets over the monotone norms: per bucket start, the first sample above it.
  std::vector<std::uint32_t> ol_bucket_;
  double ol_bucket_scale_ = 0.0;
  double ol_interp_error_ = 0.0;
};

}  // namespace softgi::sh
