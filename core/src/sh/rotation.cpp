// General SH rotation: the Ivanic-Ruedenberg recurrence and a slow fitted reference.
//
// Band l of the rotation is the (2l+1)x(2l+1) matrix B_l with f'_l = B_l f_l and f'(s) = f(R^T s).
// Band 0 is [1]. Band 1 follows from y_1(s) = c P s with P the (y, z, x) row permutation:
// f(R^T s) = f . (c P R^T s) = (P R P^T f) . y_1(s), so B_1[i][j] = R[p(i)][p(j)], p = (1, 2, 0).
// This is Ivanic and Ruedenberg's R^1. (The recurrence is unchanged by a (-1)^m phase convention:
// every term of R^l_{mn} carries the same sign (-1)^(m+n).) Bands l >= 2 follow from B_1 and B_{l-1} with their eq. 8.7 (coefficients u, v, w of
// table 1, functions U, V, W and P of table 2). The recurrence only couples representation matrices,
// so it yields B_l for whichever group element B_1 represents.
//
// Errata. Table 2's V for m < 0 is misprinted in both papers (as quoted by other implementations):
// the 1996 paper has P(1, m+1, n) (1 + d(m,-1)) + P(-1, -m-1, n) sqrt(1 - d(m,-1)), the 1998
// correction (J. Phys. Chem. A 102, 9099) P(1, m+1, n) (1 - d(m,-1)) + P(-1, -m-1, n) sqrt(1 - d(m,-1)).
// The right form, used here, mirrors the m > 0 branch:
//     V(m < 0) = P(1, m+1, n) (1 - d(m,-1)) + P(-1, -m-1, n) sqrt(1 + d(m,-1)),
// i.e. sqrt 2 P(-1, 0, n) at m = -1. Checked against the fitted reference at orders 2..8: both
// printed forms give O(0.5) errors from band 2 on, as does a + sign in W for m < 0 from band 3 on.
// The denominators of u, v, w are (l+n)(l-n) for |n| < l and 2l(2l-1) for |n| = l.
// tests/unit/test_rotation.cpp checks every band against that reference.
#include "softgi/sh/rotation.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace softgi::sh {
namespace {

constexpr int band_dim(int l) { return 2 * l + 1; }

// Offsets of the band blocks in the packed storage; a prefix of these serves every order.
constexpr std::array<int, kMaxOrder + 1> make_offsets() {
  std::array<int, kMaxOrder + 1> o{};
  for (int l = 0; l < kMaxOrder; ++l) o[l + 1] = o[l] + band_dim(l) * band_dim(l);
  return o;
}
constexpr std::array<int, kMaxOrder + 1> kOffsets = make_offsets();
constexpr int kTotalBlockSize = kOffsets[kMaxOrder];

// The rotation matrix check is loose on purpose: it catches a scaled matrix, a reflection or
// garbage, and accepts a rotation assembled in float (errors of a few 1e-7).
constexpr double kRotationTolerance = 1e-4;

// I-R table 1 coefficients, per (l, m, n), packed like the blocks. Depend on l, m, n only.
struct Uvw {
  double u, v, w;
};
struct UvwTable {
  std::array<Uvw, kTotalBlockSize> c{};
};

UvwTable build_uvw_table() {
  UvwTable t;
  for (int l = 2; l < kMaxOrder; ++l) {
    const int dim = band_dim(l);
    for (int m = -l; m <= l; ++m) {
      for (int n = -l; n <= l; ++n) {
        const int am = m < 0 ? -m : m;
        const int an = n < 0 ? -n : n;
        const double d = m == 0 ? 1.0 : 0.0;
        const double denom = an == l ? 2.0 * l * (2.0 * l - 1.0) : double((l + n) * (l - n));
        Uvw& c = t.c[kOffsets[l] + (m + l) * dim + (n + l)];
        c.u = std::sqrt(double((l + m) * (l - m)) / denom);
        c.v = 0.5 * std::sqrt((1.0 + d) * double((l + am - 1) * (l + am)) / denom) * (1.0 - 2.0 * d);
        const int wprod = (l - am - 1) * (l - am);  // -1 * 0 at |m| = l: zero, never negative otherwise
        c.w = wprod > 0 ? -0.5 * std::sqrt(double(wprod) / denom) * (1.0 - d) : 0.0;
      }
    }
  }
  return t;
}

const UvwTable& uvw_table() {
  static const UvwTable table = build_uvw_table();  // thread-safe one-time initialisation
  return table;
}

// I-R function P^l_{i,a,b}: r1 is the band-1 block, rp the band-(l-1) block, both row-major,
// indices centred (m + l). Valid for |i| <= 1, |a| <= l-1, |b| <= l.
inline double p_fn(const double* r1, const double* rp, int l, int i, int a, int b) {
  const int lp = l - 1;
  const int dim = 2 * lp + 1;
  const double* r1_row = r1 + (i + 1) * 3;  // r1_row[0] = R1(i,-1), [1] = R1(i,0), [2] = R1(i,1)
  const double* rp_row = rp + (a + lp) * dim;
  if (b == l) return r1_row[2] * rp_row[2 * lp] - r1_row[0] * rp_row[0];
  if (b == -l) return r1_row[2] * rp_row[0] + r1_row[0] * rp_row[2 * lp];
  return r1_row[1] * rp_row[b + lp];
}

constexpr double kSqrt2 = 1.41421356237309504880;

inline double u_fn(const double* r1, const double* rp, int l, int m, int n) {
  return p_fn(r1, rp, l, 0, m, n);
}

inline double v_fn(const double* r1, const double* rp, int l, int m, int n) {
  if (m == 0) return p_fn(r1, rp, l, 1, 1, n) + p_fn(r1, rp, l, -1, -1, n);
  if (m > 0) {
    if (m == 1) return kSqrt2 * p_fn(r1, rp, l, 1, 0, n);
    return p_fn(r1, rp, l, 1, m - 1, n) - p_fn(r1, rp, l, -1, -m + 1, n);
  }
  if (m == -1) return kSqrt2 * p_fn(r1, rp, l, -1, 0, n);  // see the errata note above
  return p_fn(r1, rp, l, 1, m + 1, n) + p_fn(r1, rp, l, -1, -m - 1, n);
}

inline double w_fn(const double* r1, const double* rp, int l, int m, int n) {
  // Only called where w != 0, i.e. 0 < |m| < l - 1.
  if (m > 0) return p_fn(r1, rp, l, 1, m + 1, n) + p_fn(r1, rp, l, -1, -m - 1, n);
  return p_fn(r1, rp, l, 1, m - 1, n) - p_fn(r1, rp, l, -1, -m + 1, n);
}

void check_rotation(const Mat3& r, const char* where) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (!std::isfinite(r[i][j])) {
        throw std::invalid_argument(std::string(where) + ": rotation matrix element (" +
                                    std::to_string(i) + ", " + std::to_string(j) + ") is not finite");
      }
    }
  }
  double err = 0.0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const double rrt = r[i][0] * r[j][0] + r[i][1] * r[j][1] + r[i][2] * r[j][2];
      err = std::max(err, std::abs(rrt - (i == j ? 1.0 : 0.0)));
    }
  }
  const double det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) -
                     r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                     r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
  if (err > kRotationTolerance || det <= 0.0) {
    throw std::invalid_argument(std::string(where) + ": matrix is not a proper rotation (max |R R^T - I| = " +
                                std::to_string(err) + ", det = " + std::to_string(det) + ")");
  }
}

Vec3<double> checked_unit(const Vec3<double>& v, const char* where, const char* what) {
  const double len = std::sqrt(dot(v, v));
  if (!std::isfinite(len) || len == 0.0) {
    throw std::invalid_argument(std::string(where) + ": " + what + " must be a finite non-zero vector");
  }
  return {v.x / len, v.y / len, v.z / len};
}

Vec3<double> cross(const Vec3<double>& a, const Vec3<double>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

// A unit vector perpendicular to unit v.
Vec3<double> any_perpendicular(const Vec3<double>& v) {
  // Cross with the coordinate axis least aligned with v: |result| >= sqrt(2/3).
  const double ax = std::abs(v.x), ay = std::abs(v.y), az = std::abs(v.z);
  Vec3<double> e{0.0, 0.0, 0.0};
  if (ax <= ay && ax <= az) {
    e.x = 1.0;
  } else if (ay <= az) {
    e.y = 1.0;
  } else {
    e.z = 1.0;
  }
  return normalize(cross(v, e));
}

// Householder reflection I - 2 u u^T for unit u.
Mat3 reflection(const Vec3<double>& u) {
  const double c[3] = {u.x, u.y, u.z};
  Mat3 h{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) h[i][j] = (i == j ? 1.0 : 0.0) - 2.0 * c[i] * c[j];
  }
  return h;
}

// Shortest-arc rotation a -> b for unit a, b with a.b >= -1/2, as the product of two reflections:
// H_a sends a to -a, then the reflection across the plane normal to h = (a + b)/|a + b| sends -a to b.
// Both mirror planes contain a x b, so the product turns about a x b by the angle between a and b.
// |a + b| >= 1 here, so nothing is ill-conditioned.
Mat3 rotation_between_near(const Vec3<double>& a, const Vec3<double>& b) {
  const Vec3<double> h = normalize(Vec3<double>{a.x + b.x, a.y + b.y, a.z + b.z});
  return multiply(reflection(h), reflection(a));
}

// --- Reference fit --------------------------------------------------------------------------

// splitmix64: a fixed, platform-independent stream for the fitting directions.
std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
double uniform01(std::uint64_t& state) { return double(splitmix64(state) >> 11) * 0x1.0p-53; }

// The best conditioned of kRefCandidates pseudo-random sets of 2l+1 directions, per band. The
// interpolation matrix Y must be invertible; the reference error is about cond(Y) * 1e-16.
constexpr int kRefCandidates = 128;
// The chosen sets have condition numbers 1.3 (band 1) .. 9.3 (band 7); a set near this bound would
// make the reference a weak check (errors ~1e-12), so building one fails loudly instead.
constexpr double kRefMaxCondition = 1e4;

struct RefDirections {
  std::array<std::vector<Vec3<double>>, kMaxOrder> dirs;  // dirs[l], l = 1..kMaxOrder-1
  std::array<double, kMaxOrder> condition{};
};

Eigen::MatrixXd band_values(int l, const std::vector<Vec3<double>>& dirs) {
  const int dim = band_dim(l);
  std::array<double, kMaxCoeffs> y{};
  Eigen::MatrixXd m(dim, dim);
  for (int k = 0; k < dim; ++k) {
    eval_basis(l + 1, dirs[k], y.data());
    for (int i = 0; i < dim; ++i) m(i, k) = y[l * l + i];
  }
  return m;
}

RefDirections build_ref_directions() {
  RefDirections out;
  for (int l = 1; l < kMaxOrder; ++l) {
    const int dim = band_dim(l);
    std::uint64_t state = 0x5EED0000ull + std::uint64_t(l);
    double best = std::numeric_limits<double>::infinity();
    for (int attempt = 0; attempt < kRefCandidates; ++attempt) {
      std::vector<Vec3<double>> dirs(dim);
      for (auto& d : dirs) {
        const double z = 2.0 * uniform01(state) - 1.0;
        const double phi = 2.0 * kPi * uniform01(state);
        const double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
        d = {rho * std::cos(phi), rho * std::sin(phi), z};
      }
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(band_values(l, dirs));
      const auto& sv = svd.singularValues();
      const double cond = sv(dim - 1) > 0.0 ? sv(0) / sv(dim - 1) : std::numeric_limits<double>::infinity();
      if (cond < best) {
        best = cond;
        out.dirs[l] = std::move(dirs);
      }
    }
    if (!(best <= kRefMaxCondition)) {
      throw std::logic_error("sh::rotation_reference_dense: no well-conditioned direction set for band " +
                             std::to_string(l));
    }
    out.condition[l] = best;
  }
  return out;
}

const RefDirections& ref_directions() {
  static const RefDirections dirs = build_ref_directions();
  return dirs;
}

}  // namespace

Mat3 rotation_from_axis_angle(const Vec3<double>& axis, double angle) {
  const Vec3<double> k = checked_unit(axis, "sh::rotation_from_axis_angle", "axis");
  if (!std::isfinite(angle)) throw std::invalid_argument("sh::rotation_from_axis_angle: angle is not finite");
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  // Rodrigues: R = c I + s [k]x + (1 - c) k k^T.
  return Mat3{{{c + t * k.x * k.x, t * k.x * k.y - s * k.z, t * k.x * k.z + s * k.y},
               {t * k.y * k.x + s * k.z, c + t * k.y * k.y, t * k.y * k.z - s * k.x},
               {t * k.z * k.x - s * k.y, t * k.z * k.y + s * k.x, c + t * k.z * k.z}}};
}

Mat3 rotation_between(const Vec3<double>& from, const Vec3<double>& to) {
  const Vec3<double> a = checked_unit(from, "sh::rotation_between", "from");
  const Vec3<double> b = checked_unit(to, "sh::rotation_between", "to");
  if (dot(a, b) >= -0.5) return rotation_between_near(a, b);
  // Wide angle: turn a onto -b (well conditioned), then by pi about an axis p perpendicular to b,
  // which sends -b to b. With p along a x b both turns share the axis, so the product is still the
  // shortest arc; when a x b vanishes (opposite vectors) any p perpendicular to b serves.
  Vec3<double> p = cross(a, b);
  const double pb = dot(p, b);  // re-orthogonalise: R a = b needs p exactly perpendicular to b
  p = {p.x - pb * b.x, p.y - pb * b.y, p.z - pb * b.z};
  const double plen = std::sqrt(dot(p, p));
  p = plen > 1e-150 ? Vec3<double>{p.x / plen, p.y / plen, p.z / plen} : any_perpendicular(b);
  const double c[3] = {p.x, p.y, p.z};
  Mat3 half_turn{};  // 2 p p^T - I
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) half_turn[i][j] = 2.0 * c[i] * c[j] - (i == j ? 1.0 : 0.0);
  }
  return multiply(half_turn, rotation_between_near(a, Vec3<double>{-b.x, -b.y, -b.z}));
}

Mat3 multiply(const Mat3& a, const Mat3& b) {
  Mat3 r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
  }
  return r;
}

Mat3 transpose(const Mat3& a) {
  Mat3 r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[i][j] = a[j][i];
  }
  return r;
}

ShRotation::ShRotation(int order, const Mat3& r) : order_(order) {
  check_order(order, "sh::ShRotation");
  check_rotation(r, "sh::ShRotation");
  offsets_ = kOffsets;
  blocks_.resize(std::size_t(kOffsets[order]));  // the only allocation
  double* blocks = blocks_.data();

  blocks[0] = 1.0;
  if (order < 2) return;

  // Band 1: R permuted to the (y, z, x) order of y_{1,-1}, y_{1,0}, y_{1,1}.
  constexpr int kPerm[3] = {1, 2, 0};
  double* r1 = blocks + kOffsets[1];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r1[i * 3 + j] = r[kPerm[i]][kPerm[j]];
  }

  const UvwTable& uvw = uvw_table();
  for (int l = 2; l < order; ++l) {
    const int dim = band_dim(l);
    const double* rp = blocks + kOffsets[l - 1];
    double* out = blocks + kOffsets[l];
    const Uvw* coeff = uvw.c.data() + kOffsets[l];
    for (int m = -l; m <= l; ++m) {
      for (int n = -l; n <= l; ++n) {
        const Uvw& c = coeff[(m + l) * dim + (n + l)];
        double v = c.v * v_fn(r1, rp, l, m, n);  // v != 0 for every m when l >= 2
        if (c.u != 0.0) v += c.u * u_fn(r1, rp, l, m, n);
        if (c.w != 0.0) v += c.w * w_fn(r1, rp, l, m, n);
        out[(m + l) * dim + (n + l)] = v;
      }
    }
  }
}

template <class T>
void ShRotation::apply(const T* f, T* out) const {
  out[0] = T(blocks_[0] * double(f[0]));
  for (int l = 1; l < order_; ++l) {
    const int dim = band_dim(l);
    const int base = l * l;
    const double* b = band(l);
    for (int i = 0; i < dim; ++i) {
      const double* row = b + i * dim;
      double acc = 0.0;  // double accumulation: the float path loses nothing beyond its final rounding
      for (int j = 0; j < dim; ++j) acc += row[j] * double(f[base + j]);
      out[base + i] = T(acc);
    }
  }
}

template void ShRotation::apply<float>(const float*, float*) const;
template void ShRotation::apply<double>(const double*, double*) const;

std::vector<double> ShRotation::dense() const {
  const int n = num_coeffs(order_);
  std::vector<double> d(std::size_t(n) * std::size_t(n), 0.0);
  for (int l = 0; l < order_; ++l) {
    const int dim = band_dim(l);
    const int base = l * l;
    const double* b = band(l);
    for (int i = 0; i < dim; ++i) {
      for (int j = 0; j < dim; ++j) d[std::size_t(base + i) * std::size_t(n) + std::size_t(base + j)] = b[i * dim + j];
    }
  }
  return d;
}

std::vector<double> rotation_reference_dense(int order, const Mat3& r) {
  check_order(order, "sh::rotation_reference_dense");
  check_rotation(r, "sh::rotation_reference_dense");
  const Mat3 rt = transpose(r);
  const int n = num_coeffs(order);
  std::vector<double> d(std::size_t(n) * std::size_t(n), 0.0);
  d[0] = 1.0;
  const RefDirections& ref = ref_directions();
  for (int l = 1; l < order; ++l) {
    const int dim = band_dim(l);
    const std::vector<Vec3<double>>& dirs = ref.dirs[l];
    std::vector<Vec3<double>> turned(dirs.size());
    for (std::size_t k = 0; k < dirs.size(); ++k) {
      const Vec3<double>& s = dirs[k];
      turned[k] = {rt[0][0] * s.x + rt[0][1] * s.y + rt[0][2] * s.z,
                   rt[1][0] * s.x + rt[1][1] * s.y + rt[1][2] * s.z,
                   rt[2][0] * s.x + rt[2][1] * s.y + rt[2][2] * s.z};
    }
    // Y[:,k] = y_l(s_k), Y'[:,k] = y_l(R^T s_k); y_l(R^T s) = A y_l(s) with A = Y' Y^-1. Then
    // f(R^T s) = f . A y_l(s) = (A^T f) . y_l(s): the block is A^T = Y^-T Y'^T, i.e. Y^T X = Y'^T.
    const Eigen::MatrixXd y = band_values(l, dirs);
    const Eigen::MatrixXd yp = band_values(l, turned);
    const Eigen::MatrixXd block = y.transpose().fullPivLu().solve(yp.transpose());
    const int base = l * l;
    for (int i = 0; i < dim; ++i) {
      for (int j = 0; j < dim; ++j) d[std::size_t(base + i) * std::size_t(n) + std::size_t(base + j)] = block(i, j);
    }
  }
  return d;
}

}  // namespace softgi::sh
