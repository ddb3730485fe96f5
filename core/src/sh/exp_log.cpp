#include "softgi/sh/exp_log.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "softgi/sh/product.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::sh {

const char* to_string(ExpMethod m) {
  switch (m) {
    case ExpMethod::PS: return "ps";
    case ExpMethod::PSStar: return "ps*";
    case ExpMethod::OL: return "ol";
    case ExpMethod::HYB: return "hyb";
    case ExpMethod::Exact: return "exact";
  }
  return "?";
}

ExpMethod parse_exp_method(const std::string& name) {
  std::string s;
  for (char c : name) s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (s == "ps") return ExpMethod::PS;
  if (s == "ps*" || s == "psstar" || s == "ps_star") return ExpMethod::PSStar;
  if (s == "ol") return ExpMethod::OL;
  if (s == "hyb") return ExpMethod::HYB;
  if (s == "exact") return ExpMethod::Exact;
  throw std::invalid_argument("unknown SH exponential method '" + name + "' (expected ps, ps*, ol, hyb or exact)");
}

int paper_squarings(double norm) {
  if (!(norm > 0.0) || !std::isfinite(norm)) return 0;
  // floor(log2 x) + 3 without a log: x = m 2^e with m in [0.5, 1) has floor(log2 x) = e - 1.
  int e = 0;
  std::frexp(norm, &e);
  return std::max(0, e + 2);
}

namespace {

template <class T>
using Buf = std::array<T, kMaxCoeffs>;

template <class T>
void check_input(int order, const T* f, const char* what) {
  check_order(order, what);
  check_finite(std::span<const T>(f, num_coeffs(order)), what);
}

template <class T>
void check_output(int order, const T* g, const char* what) {
  for (int i = 0; i < num_coeffs(order); ++i) {
    if (!std::isfinite(g[i])) {
      std::ostringstream os;
      os << what << ": result coefficient " << i << " overflowed to " << g[i]
         << " (the input's exponential exceeds the range of the floating-point type)";
      throw std::overflow_error(os.str());
    }
  }
}

template <class T>
double norm_without_dc(int order, const T* f) {
  double s = 0.0;
  for (int i = 1; i < num_coeffs(order); ++i) s += static_cast<double>(f[i]) * f[i];
  return std::sqrt(s);
}

// exp(f0 / sqrt(4 pi) / 2^s): the DC factor of eq. (20), taken to the 2^-s power so that it is
// applied before the squarings. In exact arithmetic this equals the paper's order (scalars commute
// with SH products); numerically it keeps every intermediate within the range of the final result,
// where multiplying exp(f0) ~ 0 by exp*(f^) ~ inf afterwards would give NaN for stiff inputs.
template <class T>
T dc_factor(const T* f, int squarings, const char* what) {
  double x = static_cast<double>(f[0]) / kSqrt4Pi / std::ldexp(1.0, squarings);
  double e = std::exp(x);
  if (e > static_cast<double>(std::numeric_limits<T>::max())) {
    std::ostringstream os;
    os << what << ": DC coefficient " << f[0] << " gives a mean log value " << f[0] / kSqrt4Pi
       << " whose exponential overflows";
    throw std::overflow_error(os.str());
  }
  return static_cast<T>(e);
}

template <class T>
void square_in_place(const TripleProduct& tp, T* g, int times, ExpStats* stats) {
  Buf<T> tmp;
  const int n2 = num_coeffs(tp.order());
  for (int s = 0; s < times; ++s) {
    tp.square(g, tmp.data());
    std::copy(tmp.data(), tmp.data() + n2, g);
  }
  if (stats) {
    stats->squarings += times;
    stats->squares += times;
  }
}

}  // namespace

template <class T>
void exp_ps(int order, const T* f, int degree, T* out, ExpStats* stats) {
  check_input(order, f, "exp_ps");
  if (degree < 0 || degree > 200) throw std::invalid_argument("exp_ps: series degree " + std::to_string(degree) + " outside [0, 200]");
  const TripleProduct& tp = TripleProduct::get(order);
  const int n2 = num_coeffs(order);
  // eq. (17): 1 + f + f^{2*}/2! + ..., powers accumulated left to right: f^{k*} = f^{(k-1)*} * f.
  Buf<T> term{}, next{};
  std::fill(out, out + n2, T(0));
  out[0] = static_cast<T>(kSqrt4Pi);
  if (degree >= 1) {
    std::copy(f, f + n2, term.data());
    for (int i = 0; i < n2; ++i) out[i] += term[i];
  }
  for (int k = 2; k <= degree; ++k) {
    tp.product(term.data(), f, next.data());
    const T inv = T(1) / T(k);
    for (int i = 0; i < n2; ++i) {
      term[i] = next[i] * inv;
      // Terms that underflow into the subnormal range contribute nothing to the sum but make every
      // later product 3x slower on x86 (measured on PS-21 in float): flush them to zero.
      if (std::abs(term[i]) < std::numeric_limits<T>::min()) term[i] = 0;
      out[i] += term[i];
    }
    if (stats) ++stats->products;
  }
  check_output(order, out, "exp_ps");
}

template <class T>
void exp_ps_star(int order, const T* f, int degree, T* out, ExpStats* stats) {
  check_input(order, f, "exp_ps_star");
  if (degree < 1 || degree > 200) throw std::invalid_argument("exp_ps_star: series degree " + std::to_string(degree) + " outside [1, 200]");
  const TripleProduct& tp = TripleProduct::get(order);
  const int n2 = num_coeffs(order);
  const int s = paper_squarings(norm_without_dc(order, f));
  const T scale = static_cast<T>(std::ldexp(1.0, -s));
  Buf<T> x{};  // f^ / 2^s (DC isolation, eq. 19; scaling, eq. 21)
  for (int i = 1; i < n2; ++i) x[i] = f[i] * scale;

  // Factored series (eq. 22): E = sum_even h_k x^k, O = sum_odd h_k x^(k-1), result E + x * O,
  // with even powers built as x^2 = x*x, x^4 = x^2*x^2, x^6 = x^4*x^2, ... (fewest products).
  Buf<T> even{}, odd{}, pw{}, x2{}, tmp{};
  even[0] = static_cast<T>(kSqrt4Pi);  // h0 = 1
  odd[0] = static_cast<T>(kSqrt4Pi);   // h1 = 1
  double fact = 1.0;                   // k!
  bool have_x2 = false;
  for (int k = 2; k <= degree; ++k) {
    fact *= k;
    if (k % 2 == 0) {
      if (k == 2) {
        tp.square(x.data(), x2.data());
        pw = x2;
        have_x2 = true;
        if (stats) ++stats->squares;
      } else if (k == 4) {
        tp.square(x2.data(), tmp.data());
        pw = tmp;
        if (stats) ++stats->squares;
      } else {
        tp.product(pw.data(), x2.data(), tmp.data());
        pw = tmp;
        if (stats) ++stats->products;
      }
      const T h = static_cast<T>(1.0 / fact);
      for (int i = 0; i < n2; ++i) even[i] += h * pw[i];
    } else {
      // odd degree k contributes h_k x^(k-1) to O; x^(k-1) is the even power built at step k-1
      const T h = static_cast<T>(1.0 / fact);
      for (int i = 0; i < n2; ++i) odd[i] += h * pw[i];
    }
  }
  (void)have_x2;
  Buf<T> result{};
  if (degree >= 3) {
    tp.product(x.data(), odd.data(), tmp.data());
    if (stats) ++stats->products;
    for (int i = 0; i < n2; ++i) result[i] = even[i] + tmp[i];
  } else {
    for (int i = 0; i < n2; ++i) result[i] = even[i] + x[i];  // x * (h1 1) = x
  }
  const T dc = dc_factor(f, s, "exp_ps_star");
  for (int i = 0; i < n2; ++i) result[i] *= dc;
  square_in_place(tp, result.data(), s, stats);
  std::copy(result.data(), result.data() + n2, out);
  check_output(order, out, "exp_ps_star");
}

namespace {
template <class T>
void ol_core(const ShTables& tables, const T* f, double norm, int squarings, T* out, ExpStats* stats, const char* what) {
  const int order = tables.order();
  const int n2 = num_coeffs(order);
  const T scale = static_cast<T>(std::ldexp(1.0, -squarings));
  Buf<T> x{};
  for (int i = 1; i < n2; ++i) x[i] = f[i] * scale;
  double a = 1.0, b = 1.0;
  tables.ol_lookup(std::ldexp(norm, -squarings), a, b);
  // eq. (23): exp*(f) ~ exp(f0/sqrt(4pi)) (a 1 + b f^)
  const T dc = dc_factor(f, squarings, what);
  Buf<T> g{};
  g[0] = static_cast<T>(a * kSqrt4Pi) * dc;
  for (int i = 1; i < n2; ++i) g[i] = static_cast<T>(b) * x[i] * dc;
  square_in_place(TripleProduct::get(order), g.data(), squarings, stats);
  std::copy(g.data(), g.data() + n2, out);
  check_output(order, out, what);
}
}  // namespace

template <class T>
void exp_ol(const ShTables& tables, const T* f, T* out, ExpStats* stats) {
  check_input(tables.order(), f, "exp_ol");
  ol_core(tables, f, norm_without_dc(tables.order(), f), 0, out, stats, "exp_ol");
}

template <class T>
void exp_hyb(const ShTables& tables, const T* f, T* out, double max_norm, ExpStats* stats) {
  check_input(tables.order(), f, "exp_hyb");
  if (!(max_norm >= 0.0) || !std::isfinite(max_norm))
    throw std::invalid_argument("exp_hyb: OL norm threshold " + std::to_string(max_norm) + " must be >= 0 and finite");
  const double norm = norm_without_dc(tables.order(), f);
  int s = 0;
  if (max_norm == 0.0) s = paper_squarings(norm);
  else if (norm > max_norm) s = static_cast<int>(std::ceil(std::log2(norm / max_norm)));
  ol_core(tables, f, norm, s, out, stats, "exp_hyb");
}

void exp_projected(int order, const double* f, double* out) {
  check_input(order, f, "exp_projected");
  // exp(f(s)) is not band-limited; 4n + 24 bands resolve the smooth reconstructions of order <= 8.
  static thread_local std::array<SphereQuadrature, kMaxOrder + 1> cache;
  SphereQuadrature& q = cache[order];
  if (q.dirs.empty()) q = make_sphere_quadrature(4 * order + 24);
  std::vector<double> g = project(order, q, [&](const Vec3<double>& s) { return std::exp(reconstruct(order, f, s)); });
  std::copy(g.begin(), g.end(), out);
  check_output(order, out, "exp_projected");
}

template <class T>
void exp(int order, const T* f, T* out, const ExpOptions& opt, const ShTables* tables, ExpStats* stats) {
  auto need_tables = [&](const char* m) {
    if (!tables) throw std::invalid_argument(std::string("SH exp method '") + m + "' needs the OL tables");
    if (tables->order() != order)
      throw std::invalid_argument("SH exp: tables built for order " + std::to_string(tables->order()) +
                                  " used at order " + std::to_string(order));
  };
  switch (opt.method) {
    case ExpMethod::PS: exp_ps(order, f, opt.degree, out, stats); return;
    case ExpMethod::PSStar: exp_ps_star(order, f, opt.degree, out, stats); return;
    case ExpMethod::OL: need_tables("ol"); exp_ol(*tables, f, out, stats); return;
    case ExpMethod::HYB: need_tables("hyb"); exp_hyb(*tables, f, out, opt.hyb_max_norm, stats); return;
    case ExpMethod::Exact: {
      std::array<double, kMaxCoeffs> fd{}, gd{};
      for (int i = 0; i < num_coeffs(order); ++i) fd[i] = f[i];
      exp_exact(order, fd.data(), gd.data());
      for (int i = 0; i < num_coeffs(order); ++i) out[i] = static_cast<T>(gd[i]);
      return;
    }
  }
}

#define SOFTGI_INSTANTIATE(T)                                                                  \
  template void exp_ps<T>(int, const T*, int, T*, ExpStats*);                                  \
  template void exp_ps_star<T>(int, const T*, int, T*, ExpStats*);                             \
  template void exp_ol<T>(const ShTables&, const T*, T*, ExpStats*);                           \
  template void exp_hyb<T>(const ShTables&, const T*, T*, double, ExpStats*);                  \
  template void exp<T>(int, const T*, T*, const ExpOptions&, const ShTables*, ExpStats*);
SOFTGI_INSTANTIATE(float)
SOFTGI_INSTANTIATE(double)
#undef SOFTGI_INSTANTIATE

}  // namespace softgi::sh
