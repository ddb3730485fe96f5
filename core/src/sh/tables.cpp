#include "softgi/sh/tables.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>

#include "softgi/sh/exp_log.hpp"

namespace softgi::sh {

namespace {
// Legendre polynomial P_l(x) by the three-term recurrence.
double legendre(int l, double x) {
  if (l == 0) return 1.0;
  double p0 = 1.0, p1 = x;
  for (int k = 2; k <= l; ++k) {
    double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

void check_theta(double theta, const char* what) {
  if (!(theta >= 0.0 && theta <= kPi / 2 + 1e-12)) {
    std::ostringstream os;
    os << what << ": angular radius theta = " << theta << " rad is outside [0, pi/2]";
    throw std::invalid_argument(os.str());
  }
}
}  // namespace

std::vector<double> cap_visibility_zh(int order, double theta) {
  check_order(order, "cap_visibility_zh");
  check_theta(theta, "cap_visibility_zh");
  const double c = std::cos(theta);
  const double one_minus_c = 2.0 * std::sin(theta / 2) * std::sin(theta / 2);  // no cancellation at theta -> 0
  std::vector<double> g(order);
  // Cap indicator: 2 pi K_l int_c^1 P_l = 2 pi K_l (P_{l-1}(c) - P_{l+1}(c)) / (2l+1), l >= 1.
  // Visibility is 1 minus the indicator (paper 004 eq. 33).
  g[0] = kSqrt4Pi - 2.0 * kPi * std::sqrt(1.0 / (4.0 * kPi)) * one_minus_c;
  for (int l = 1; l < order; ++l) {
    double kl = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi));
    g[l] = -2.0 * kPi * kl * (legendre(l - 1, c) - legendre(l + 1, c)) / (2.0 * l + 1.0);
  }
  return g;
}

std::vector<double> cap_log_zh(int order, double theta, double log_threshold) {
  std::vector<double> zh = cap_visibility_zh(order, theta);
  std::array<double, kMaxCoeffs> g{}, f{};
  for (int l = 0; l < order; ++l) g[index(l, 0)] = zh[l];
  log_eigen(order, g.data(), f.data(), log_threshold);
  std::vector<double> out(order);
  for (int l = 0; l < order; ++l) out[l] = f[index(l, 0)];
  return out;
}

template <class T>
void Table1D::lookup(double xv, T* out) const {
  const int n = rows();
  // Samples are uniform in the table's own parameter (theta or alpha).
  double t = (xv - x.front()) / (x.back() - x.front()) * (n - 1);
  if (!(t > 0.0)) t = 0.0;  // also maps NaN to the first row
  if (t > n - 1) t = n - 1;
  int k = std::min(static_cast<int>(t), n - 2);
  double w = t - k;
  const double* a = row(k);
  const double* b = row(k + 1);
  for (int i = 0; i < width; ++i) out[i] = static_cast<T>(a[i] + w * (b[i] - a[i]));
}
template void Table1D::lookup<float>(double, float*) const;
template void Table1D::lookup<double>(double, double*) const;

namespace {
// Samples a function of theta on the table grid; with measure_error, compares linear
// interpolation against the function itself at every midpoint.
Table1D build_table(const TableOptions& opt, int width, const std::function<std::vector<double>(double theta)>& fn) {
  Table1D t;
  t.param = opt.param;
  t.width = width;
  const int r = opt.resolution;
  auto theta_of = [&](double x) { return opt.param == TableParam::Theta ? x : std::asin(std::min(1.0, x)); };
  const double xmax = opt.param == TableParam::Theta ? kPi / 2 : 1.0;
  t.x.resize(r);
  t.data.resize(static_cast<std::size_t>(r) * width);
  for (int k = 0; k < r; ++k) {
    t.x[k] = xmax * k / (r - 1);
    std::vector<double> v = fn(theta_of(t.x[k]));
    std::copy(v.begin(), v.begin() + width, t.data.begin() + static_cast<std::size_t>(k) * width);
  }
  if (opt.measure_error) {
    std::vector<double> interp(width);
    for (int k = 0; k + 1 < r; ++k) {
      double xm = 0.5 * (t.x[k] + t.x[k + 1]);
      std::vector<double> exact = fn(theta_of(xm));
      t.lookup(xm, interp.data());
      for (int i = 0; i < width; ++i) {
        double e = std::abs(interp[i] - exact[i]);
        if (e > t.max_interp_error) {
          t.max_interp_error = e;
          t.max_interp_error_at = xm;
        }
      }
    }
  }
  return t;
}

struct OlSample {
  double norm, a, b;
};
// Paper 004 eq. 24 for one cap: least-squares projection of g^ = exp(-f0/sqrt(4pi)) g onto 1 and f^.
OlSample ol_sample(int order, double theta, double log_threshold) {
  std::vector<double> g = cap_visibility_zh(order, theta);
  std::vector<double> f = cap_log_zh(order, theta, log_threshold);
  double scale = std::exp(-f[0] / kSqrt4Pi);
  double ff = 0.0, gf = 0.0;
  for (int l = 1; l < order; ++l) {
    ff += f[l] * f[l];
    gf += scale * g[l] * f[l];
  }
  OlSample s;
  s.norm = std::sqrt(ff);
  s.a = scale * g[0] / kSqrt4Pi;
  // theta -> 0: g^ -> 1 + f^ to first order, so b -> 1.
  s.b = ff > 1e-24 ? gf / ff : 1.0;
  return s;
}
}  // namespace

ShTables::ShTables(const TableOptions& opt) : opt_(opt) {
  check_order(opt.order, "ShTables");
  if (opt.resolution < 2 || opt.resolution > 1 << 16)
    throw std::invalid_argument("ShTables: table resolution " + std::to_string(opt.resolution) + " outside [2, 65536]");
  if (!(opt.log_threshold > 0.0 && opt.log_threshold < 1.0))
    throw std::invalid_argument("ShTables: log threshold " + std::to_string(opt.log_threshold) + " outside (0, 1)");
  const int n = opt.order;
  cap_vis_ = build_table(opt, n, [&](double th) { return cap_visibility_zh(n, th); });
  cap_log_ = build_table(opt, n, [&](double th) { return cap_log_zh(n, th, opt.log_threshold); });
  d_avg_ = build_table(opt, n, [&](double th) { return indirect_D_quadrature(n, std::sin(th)); });
  d_poly_ = build_table(opt, 3, [&](double th) {
    auto d = indirect_D_polynomial(std::sin(th));
    return std::vector<double>(d.begin(), d.end());
  });
  sl_w_ = build_table(opt, n, [&](double th) { return spherical_light_weight_zh(n, std::sin(th)); });
  if (opt.exact_indirect_operator) {
    const int n4 = num_coeffs(n) * num_coeffs(n);
    m_exact_ = build_table(opt, n4, [&](double th) { return indirect_M(n, std::sin(th)); });
  }

  for (int k = 0; k < cap_vis_.rows(); ++k) {
    double x = cap_vis_.x[k];
    double th = opt.param == TableParam::Theta ? x : std::asin(std::min(1.0, x));
    OlSample s = ol_sample(n, th, opt.log_threshold);
    ol_norm_.push_back(s.norm);
    ol_a_.push_back(s.a);
    ol_b_.push_back(s.b);
  }
  // The runtime lookup is by ||f^||: keep the prefix of the sweep where the norm increases.
  for (std::size_t k = 0; k < ol_norm_.size(); ++k) {
    if (!ol_norm_mono_.empty() && !(ol_norm_[k] > ol_norm_mono_.back())) break;
    ol_norm_mono_.push_back(ol_norm_[k]);
    ol_a_mono_.push_back(ol_a_[k]);
    ol_b_mono_.push_back(ol_b_[k]);
  }
  // ol_lookup runs per exponential (millions a frame): instead of a binary search over the whole
  // sweep it searches the cells that a bucket and its two neighbours reach. The neighbours cover
  // the rounding of the bucket coordinate; the sample found is the binary search's.
  if (ol_norm_mono_.size() >= 2) {
    const std::size_t nb = ol_norm_mono_.size();
    const double x0 = ol_norm_mono_.front();
    ol_bucket_scale_ = static_cast<double>(nb) / (ol_norm_mono_.back() - x0);
    ol_bucket_.resize(nb + 1);
    for (std::size_t b = 0; b <= nb; ++b)
      ol_bucket_[b] = static_cast<std::uint32_t>(
          std::upper_bound(ol_norm_mono_.begin(), ol_norm_mono_.end(), x0 + static_cast<double>(b) / ol_bucket_scale_) -
          ol_norm_mono_.begin());
  }
  if (opt.measure_error) {
    // OL interpolation error: a, b looked up at the norm of a midpoint cap against that cap's own a, b.
    for (std::size_t k = 0; k + 1 < ol_norm_mono_.size(); ++k) {
      double x = 0.5 * (cap_vis_.x[k] + cap_vis_.x[k + 1]);
      double th = opt.param == TableParam::Theta ? x : std::asin(std::min(1.0, x));
      OlSample s = ol_sample(n, th, opt.log_threshold);
      double a, b;
      ol_lookup(s.norm, a, b);
      ol_interp_error_ = std::max({ol_interp_error_, std::abs(a - s.a), std::abs(b - s.b)});
    }
  }
}

void ShTables::ol_lookup(double norm, double& a, double& b) const {
  const auto& xs = ol_norm_mono_;
  if (xs.empty() || !(norm > xs.front())) {
    a = ol_a_mono_.empty() ? 1.0 : ol_a_mono_.front();
    b = ol_b_mono_.empty() ? 1.0 : ol_b_mono_.front();
    return;
  }
  if (norm >= xs.back()) {
    a = ol_a_mono_.back();
    b = ol_b_mono_.back();
    return;
  }
  const std::size_t nb = ol_bucket_.size() - 1;
  const std::size_t bucket = std::min(static_cast<std::size_t>((norm - xs.front()) * ol_bucket_scale_), nb - 1);
  const auto lo = xs.begin() + ol_bucket_[bucket > 0 ? bucket - 1 : 0], hi = xs.begin() + ol_bucket_[std::min(bucket + 2, nb)];
  std::size_t k = static_cast<std::size_t>(std::upper_bound(lo, hi, norm) - xs.begin()) - 1;
  double w = (norm - xs[k]) / (xs[k + 1] - xs[k]);
  a = ol_a_mono_[k] + w * (ol_a_mono_[k + 1] - ol_a_mono_[k]);
  b = ol_b_mono_[k] + w * (ol_b_mono_[k + 1] - ol_b_mono_[k]);
}

std::size_t ShTables::bytes() const {
  std::size_t b = 0;
  for (const Table1D* t : {&cap_vis_, &cap_log_, &d_avg_, &d_poly_, &sl_w_, &m_exact_}) b += (t->data.size() + t->x.size()) * sizeof(double);
  b += (ol_norm_.size() + ol_a_.size() + ol_b_.size() + ol_norm_mono_.size() * 3) * sizeof(double);
  return b;
}

}  // namespace softgi::sh
