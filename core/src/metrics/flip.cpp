// FLIP and HDR-FLIP (docs/metrics.md#flip).
//
// Sources: Andersson, Nilsson, Akenine-Moller, Oskarsson, Astrom, Fairchild 2020, "FLIP: A Difference
// Evaluator for Alternating Images" (LDR-FLIP, "FLIP 2020" below), and Andersson, Nilsson, Akenine-Moller
// 2021, "Visualizing and Communicating Errors in Rendered Images", Ray Tracing Gems II chapter 19, with
// the exposure-range construction of Andersson, Nilsson, Shirley, Akenine-Moller 2021, "Visualizing
// Errors in Rendered High Dynamic Range Images" (HDR-FLIP, "HDR-FLIP 2021" below). The constants were
// checked against the authors' published reference implementation (NVlabs/flip, flip_api.py).
#include "softgi/metrics/flip.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace softgi::metrics {

namespace {

using Plane = std::vector<float>;
using Mat3 = std::array<std::array<double, 3>, 3>;

constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------------------------------------------
// Constants (FLIP 2020 unless noted).

// Linear sRGB (Rec. 709 primaries, D65) to CIE XYZ as exact rationals, the form the authors use. The
// reference white of YCxCz and CIELAB is this matrix applied to RGB (1, 1, 1) = (0.950428545, 1,
// 1.088900371), so display white is exactly L* = 100, a* = b* = 0.
constexpr Mat3 kRgbToXyz = {{{10135552.0 / 24577794.0, 8788810.0 / 24577794.0, 4435075.0 / 24577794.0},
                             {2613072.0 / 12288897.0, 8788810.0 / 12288897.0, 887015.0 / 12288897.0},
                             {1425312.0 / 73733382.0, 8788810.0 / 73733382.0, 70074185.0 / 73733382.0}}};

// Contrast sensitivity functions as sums of Gaussians in the frequency domain,
// CSF(f) = a1 exp(-b1 f^2) + a2 exp(-b2 f^2), whose spatial form is
// S(x) = a1 sqrt(pi / b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi / b2) exp(-pi^2 x^2 / b2), x in degrees.
// The paper's fits for the achromatic (A), red-green (RG) and blue-yellow (BY) channels. A and RG are
// single Gaussians (a2 = 0); b2 = 1e-5 there only keeps sqrt(pi / b2) finite and never contributes.
struct Csf {
  double a1, b1, a2, b2;
};
constexpr Csf kCsfAchromatic{1.0, 0.0047, 0.0, 1e-5};
constexpr Csf kCsfRedGreen{1.0, 0.0053, 0.0, 1e-5};
constexpr Csf kCsfBlueYellow{34.1, 0.04, 13.5, 0.025};
// The filter radius comes from the widest Gaussian of all three channels, 3 standard deviations:
// the spatial Gaussian exp(-pi^2 x^2 / b) has sigma = sqrt(b / (2 pi^2)) degrees.
constexpr double kCsfSigmas = 3.0;

// Colour metric: exponent on the HyAB distance, and the redistribution that sends [0, pc cmax) to
// [0, pt) and [pc cmax, cmax] to [pt, 1], cmax being the (exponentiated) HyAB distance between
// Hunt-adjusted green and blue, the largest between two colours in the unit RGB cube.
constexpr double kQc = 0.7;
constexpr double kPc = 0.4;
constexpr double kPt = 0.95;
// Hunt effect: chroma scales with lightness, a* and b* times 0.01 L*.
constexpr double kHunt = 0.01;

// Feature metric: the edge / point detectors are the first / second derivative of a Gaussian whose
// peak-to-trough distance (2 sigma) is w = 0.082 degrees, sampled over 3 sigma; the feature
// difference is normalised by 1/sqrt(2) (the largest possible gradient-magnitude difference with
// unit-normalised detector lobes is sqrt(2)) and raised to qf.
constexpr double kFeatureW = 0.082;
constexpr double kFeatureSigmas = 3.0;
constexpr double kQf = 0.5;

// HDR-FLIP 2021: the start exposure maps the reference's largest luminance, and the stop exposure its
// median luminance, to this tone-mapped value.
constexpr double kExposureTarget = 0.85;

// ---------------------------------------------------------------------------------------------------
// Input checks (the conventions of image_metrics.cpp).

std::string size_str(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void check_image(const Image& img, const char* role) {
  if (img.width <= 0 || img.height <= 0 || img.empty())
    throw std::invalid_argument(std::string("FLIP: ") + role + " image is empty (" + size_str(img.width, img.height) +
                                ")");
  const std::size_t n = static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height);
  if (img.rgb.size() != n)
    throw std::invalid_argument(std::string("FLIP: ") + role + " image: pixel buffer holds " +
                                std::to_string(img.rgb.size()) + " pixels, expected " +
                                size_str(img.width, img.height) + " = " + std::to_string(n));
}

// Row-major scan, so the error names the first bad pixel in reading order.
void check_values(const Image& img, const char* role, bool unit_range) {
  static const char* kChannel[3] = {"R", "G", "B"};
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const glm::vec3& p = img.at(x, y);
      for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(p[c])) {
          std::ostringstream os;
          os << "FLIP: " << role << " image has a non-finite value " << p[c] << " in channel " << kChannel[c]
             << " at pixel (" << x << ", " << y << ")";
          throw std::invalid_argument(os.str());
        }
        if (unit_range && (p[c] < 0.0f || p[c] > 1.0f)) {
          std::ostringstream os;
          os << "FLIP: " << role << " image has a value " << p[c] << " outside [0, 1] in channel " << kChannel[c]
             << " at pixel (" << x << ", " << y
             << "); LDR-FLIP takes sRGB-encoded display values (use HDR-FLIP for linear HDR images)";
          throw std::invalid_argument(os.str());
        }
      }
    }
}

void check_pair(const Image& test, const Image& ref, bool unit_range) {
  check_image(test, "test");
  check_image(ref, "reference");
  if (test.width != ref.width || test.height != ref.height)
    throw std::invalid_argument("FLIP: image sizes differ: test image " + size_str(test.width, test.height) +
                                ", reference image " + size_str(ref.width, ref.height));
  check_values(test, "test", unit_range);
  check_values(ref, "reference", unit_range);
}

void check_ppd(double ppd) {
  if (!std::isfinite(ppd) || ppd < kFlipMinPpd || ppd > kFlipMaxPpd) {
    std::ostringstream os;
    os << "FLIP: pixels per degree (ppd) must be in [" << kFlipMinPpd << ", " << kFlipMaxPpd << "], got " << ppd;
    throw std::invalid_argument(os.str());
  }
}

// ---------------------------------------------------------------------------------------------------
// Colour transforms, in double per pixel.

Mat3 inverse(const Mat3& m) {
  const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  const double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
  Mat3 r{};
  r[0][0] = c00 / det;
  r[1][0] = c01 / det;
  r[2][0] = c02 / det;
  r[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  r[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  r[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  r[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  r[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  r[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  return r;
}

glm::dvec3 mul(const Mat3& m, const glm::dvec3& v) {
  return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
          m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}

struct ColorSpace {
  Mat3 xyz_to_rgb = inverse(kRgbToXyz);
  glm::dvec3 white = mul(kRgbToXyz, glm::dvec3(1.0));
};
const ColorSpace& color_space() {
  static const ColorSpace cs;
  return cs;
}

// IEC 61966-2-1 sRGB decoding.
double srgb_to_linear(double c) { return c > 0.04045 ? std::pow((c + 0.055) / 1.055, 2.4) : c / 12.92; }

// CIELAB's cube root with its linear segment below (6/29)^3.
double lab_f(double t) {
  constexpr double d = 6.0 / 29.0;
  return t > d * d * d ? std::cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

// Linear RGB -> CIELAB (relative to the white above) -> Hunt-adjusted (L, 0.01 L a, 0.01 L b).
glm::dvec3 hunt_lab(const glm::dvec3& rgb) {
  const ColorSpace& cs = color_space();
  const glm::dvec3 xyz = mul(kRgbToXyz, rgb) / cs.white;
  const double fx = lab_f(xyz.x), fy = lab_f(xyz.y), fz = lab_f(xyz.z);
  const double l = 116.0 * fy - 16.0, a = 500.0 * (fx - fy), b = 200.0 * (fy - fz);
  return {l, kHunt * l * a, kHunt * l * b};
}

// HyAB (Abasi, Tehran, Fairchild 2020, as FLIP 2020 uses it): city-block in lightness, Euclidean in the
// chromatic plane; large colour differences are judged this way better than by Euclidean Delta E.
double hyab(const glm::dvec3& p, const glm::dvec3& q) {
  return std::abs(p.x - q.x) + std::hypot(p.y - q.y, p.z - q.z);
}

double color_cmax() {
  static const double cmax = std::pow(hyab(hunt_lab({0.0, 1.0, 0.0}), hunt_lab({0.0, 0.0, 1.0})), kQc);
  return cmax;
}

double redistribute(double e, double cmax) {
  const double knee = kPc * cmax;
  const double r = e < knee ? e * (kPt / knee) : kPt + (e - knee) / (cmax - knee) * (1.0 - kPt);
  // cmax is the largest distance in the RGB cube; only float rounding in the filtered planes can push
  // e past it, by a few ulps.
  return std::min(r, 1.0);
}

// ---------------------------------------------------------------------------------------------------
// Separable filtering with clamp-to-edge borders (the authors' border mode). Kernels are stored as
// their non-negative half, k[j] the weight of offset +j; the weight of offset -j is k[j] (even), -k[j]
// (odd, first derivative), or k[j] with the centre weight -2 sum_{j>0} k[j] (even with zero sum, second
// derivative). The derivative forms are evaluated as sums of differences so that a flat region gives
// exactly 0: the feature difference is raised to qf = 0.5, which would turn 1e-8 of rounding into 1e-4.

enum class Symmetry { even, odd, even_zero_sum };

struct Kernel {
  Symmetry symmetry = Symmetry::even;
  std::vector<float> k;  // k[0 .. radius]
  int radius() const { return static_cast<int>(k.size()) - 1; }
};

template <Symmetry S, class Left, class Right>
inline float taps(const float* k, int r, float centre, Left&& left, Right&& right) {
  float acc = 0.0f;
  if constexpr (S == Symmetry::even) {
    acc = k[0] * centre;
    for (int j = 1; j <= r; ++j) acc += k[j] * (right(j) + left(j));
  } else if constexpr (S == Symmetry::odd) {
    for (int j = 1; j <= r; ++j) acc += k[j] * (right(j) - left(j));
  } else {
    const float twice = 2.0f * centre;
    for (int j = 1; j <= r; ++j) acc += k[j] * ((right(j) + left(j)) - twice);
  }
  return acc;
}

template <Symmetry S>
void filter_rows_impl(const Plane& in, Plane& out, int w, int h, const Kernel& kern) {
  const int r = kern.radius();
  const float* k = kern.k.data();
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const float* s = in.data() + static_cast<std::size_t>(y) * w;
      float* d = out.data() + static_cast<std::size_t>(y) * w;
      for (int x = 0; x < w; ++x) {
        if (x >= r && x + r < w) {
          d[x] = taps<S>(k, r, s[x], [&](int j) { return s[x - j]; }, [&](int j) { return s[x + j]; });
        } else {
          d[x] = taps<S>(
              k, r, s[x], [&](int j) { return s[std::max(x - j, 0)]; },
              [&](int j) { return s[std::min(x + j, w - 1)]; });
        }
      }
    }
  });
}

template <Symmetry S>
void filter_cols_impl(const Plane& in, Plane& out, int w, int h, const Kernel& kern) {
  const int r = kern.radius();
  const float* k = kern.k.data();
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const float* c = in.data() + static_cast<std::size_t>(y) * w;
      float* d = out.data() + static_cast<std::size_t>(y) * w;
      if constexpr (S == Symmetry::even) {
        for (int x = 0; x < w; ++x) d[x] = k[0] * c[x];
      } else {
        std::fill(d, d + w, 0.0f);
      }
      for (int j = 1; j <= r; ++j) {
        const float* up = in.data() + static_cast<std::size_t>(std::max(y - j, 0)) * w;
        const float* dn = in.data() + static_cast<std::size_t>(std::min(y + j, h - 1)) * w;
        const float kj = k[j];
        if constexpr (S == Symmetry::even) {
          for (int x = 0; x < w; ++x) d[x] += kj * (dn[x] + up[x]);
        } else if constexpr (S == Symmetry::odd) {
          for (int x = 0; x < w; ++x) d[x] += kj * (dn[x] - up[x]);
        } else {
          for (int x = 0; x < w; ++x) d[x] += kj * ((dn[x] + up[x]) - 2.0f * c[x]);
        }
      }
    }
  });
}

void filter_rows(const Plane& in, Plane& out, int w, int h, const Kernel& kern) {
  switch (kern.symmetry) {
    case Symmetry::even: filter_rows_impl<Symmetry::even>(in, out, w, h, kern); break;
    case Symmetry::odd: filter_rows_impl<Symmetry::odd>(in, out, w, h, kern); break;
    case Symmetry::even_zero_sum: filter_rows_impl<Symmetry::even_zero_sum>(in, out, w, h, kern); break;
  }
}

void filter_cols(const Plane& in, Plane& out, int w, int h, const Kernel& kern) {
  switch (kern.symmetry) {
    case Symmetry::even: filter_cols_impl<Symmetry::even>(in, out, w, h, kern); break;
    case Symmetry::odd: filter_cols_impl<Symmetry::odd>(in, out, w, h, kern); break;
    case Symmetry::even_zero_sum: filter_cols_impl<Symmetry::even_zero_sum>(in, out, w, h, kern); break;
  }
}

// ---------------------------------------------------------------------------------------------------
// Kernels.

// One channel's CSF filter as a weighted sum of separable Gaussians. FLIP 2020 normalises the sampled 2D
// kernel S(x, y) to unit sum; with S = sum_i A_i e_i(x) e_i(y) (A_i = a_i sqrt(pi / b_i), e_i the
// sampled 1D Gaussian), the normalised kernel is sum_i w_i (e_i / E_i)(x) (e_i / E_i)(y) with
// E_i = sum e_i and w_i = A_i E_i^2 / sum_m A_m E_m^2: exactly separable per term.
struct CsfFilter {
  std::vector<Kernel> row, col;  // per Gaussian term; the term weight is folded into `col`
};

CsfFilter make_csf_filter(const Csf& csf, double ppd, int radius) {
  const std::array<double, 2> a = {csf.a1, csf.a2}, b = {csf.b1, csf.b2};
  std::array<std::vector<double>, 2> e;
  std::array<double, 2> mass{};  // A_i E_i^2
  double total = 0.0;
  for (int t = 0; t < 2; ++t) {
    if (a[t] == 0.0) continue;
    e[t].resize(static_cast<std::size_t>(radius) + 1);
    double sum = 0.0;
    for (int j = 0; j <= radius; ++j) {
      const double xdeg = j / ppd;
      e[t][j] = std::exp(-kPi * kPi * xdeg * xdeg / b[t]);
      sum += (j == 0 ? 1.0 : 2.0) * e[t][j];
    }
    for (double& v : e[t]) v /= sum;
    mass[t] = a[t] * std::sqrt(kPi / b[t]) * sum * sum;
    total += mass[t];
  }
  CsfFilter f;
  for (int t = 0; t < 2; ++t) {
    if (a[t] == 0.0) continue;
    const double weight = mass[t] / total;
    Kernel kr, kc;
    for (double v : e[t]) {
      kr.k.push_back(static_cast<float>(v));
      kc.k.push_back(static_cast<float>(v * weight));
    }
    f.row.push_back(std::move(kr));
    f.col.push_back(std::move(kc));
  }
  return f;
}

int csf_radius(double ppd) {
  const double bmax = std::max({kCsfAchromatic.b1, kCsfAchromatic.b2, kCsfRedGreen.b1, kCsfRedGreen.b2,
                                kCsfBlueYellow.b1, kCsfBlueYellow.b2});
  return static_cast<int>(std::ceil(kCsfSigmas * std::sqrt(bmax / (2.0 * kPi * kPi)) * ppd));
}

// The feature detectors of FLIP 2020: Gaussian derivatives along x (and their transposes along y), with
// the positive and the negative weights of the 2D kernel normalised separately to sum to +1 and -1. The
// 2D kernel is d(x) g(y); normalising its positive part to 1 normalises d's positive part to 1 and g to
// unit sum, so the separable kernels below are exactly the normalised 2D ones.
struct FeatureKernels {
  Kernel gauss, edge, point;
};

FeatureKernels make_feature_kernels(double ppd) {
  const double sd = 0.5 * kFeatureW * ppd;
  const int r = static_cast<int>(std::ceil(kFeatureSigmas * sd));
  std::vector<double> g(static_cast<std::size_t>(r) + 1), d(g.size()), p(g.size());
  double gsum = 0.0, dpos = 0.0, ppos = 0.0, pneg = 0.0;
  for (int j = 0; j <= r; ++j) {
    const double x = j;
    g[j] = std::exp(-x * x / (2.0 * sd * sd));
    d[j] = -x * g[j];                          // first derivative (up to the constant 1/sd^2)
    p[j] = (x * x / (sd * sd) - 1.0) * g[j];  // second derivative (up to 1/sd^2)
    const double count = j == 0 ? 1.0 : 2.0;  // offsets +j and -j
    gsum += count * g[j];
    if (j > 0) dpos += x * g[j];  // the positive lobe of d: offsets -j
    if (p[j] > 0.0) ppos += count * p[j];
    if (p[j] < 0.0) pneg -= count * p[j];
  }
  FeatureKernels fk;
  fk.gauss.symmetry = Symmetry::even;
  fk.edge.symmetry = Symmetry::odd;
  fk.point.symmetry = Symmetry::even_zero_sum;
  for (int j = 0; j <= r; ++j) {
    fk.gauss.k.push_back(static_cast<float>(g[j] / gsum));
    fk.edge.k.push_back(static_cast<float>(d[j] / dpos));
    fk.point.k.push_back(static_cast<float>(p[j] > 0.0 ? p[j] / ppos : p[j] / pneg));
  }
  return fk;
}

struct Kernels {
  CsfFilter achromatic, red_green, blue_yellow;
  FeatureKernels feature;
  double cmax = 0.0;
};

Kernels make_kernels(double ppd) {
  const int r = csf_radius(ppd);
  Kernels k;
  k.achromatic = make_csf_filter(kCsfAchromatic, ppd, r);
  k.red_green = make_csf_filter(kCsfRedGreen, ppd, r);
  k.blue_yellow = make_csf_filter(kCsfBlueYellow, ppd, r);
  k.feature = make_feature_kernels(ppd);
  k.cmax = color_cmax();
  return k;
}

// ---------------------------------------------------------------------------------------------------
// LDR-FLIP on linear RGB in [0, 1].

Plane apply_csf(const Plane& in, int w, int h, const CsfFilter& f) {
  const std::size_t n = in.size();
  Plane tmp(n), term(n), out;
  for (std::size_t t = 0; t < f.row.size(); ++t) {
    filter_rows(in, tmp, w, h, f.row[t]);
    if (t == 0) {
      out.resize(n);
      filter_cols(tmp, out, w, h, f.col[t]);
    } else {
      filter_cols(tmp, term, w, h, f.col[t]);
      for (std::size_t i = 0; i < n; ++i) out[i] += term[i];
    }
  }
  return out;
}

// One image's share of the metric: its CSF-filtered, Hunt-adjusted CIELAB and its feature magnitudes.
struct Prepared {
  Plane l, a, b;       // Hunt-adjusted L*a*b* of the filtered image
  Plane edge, point;   // |(edge_x, edge_y)| and |(point_x, point_y)| of the achromatic channel
};

Prepared prepare(const std::vector<glm::vec3>& linear, int w, int h, const Kernels& k) {
  const ColorSpace& cs = color_space();
  const std::size_t n = linear.size();
  // YCxCz, the linearised CIELAB of Kolpatzik and Bouman that FLIP 2020 filters in: the CSFs apply to
  // contrast, which is linear in these channels. achromatic = Y / Yn = (YCxCz's Y + 16) / 116.
  Plane yy(n), cx(n), cz(n), achromatic(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const glm::dvec3 xyz = mul(kRgbToXyz, glm::dvec3(linear[i])) / cs.white;
      yy[i] = static_cast<float>(116.0 * xyz.y - 16.0);
      cx[i] = static_cast<float>(500.0 * (xyz.x - xyz.y));
      cz[i] = static_cast<float>(200.0 * (xyz.y - xyz.z));
      achromatic[i] = static_cast<float>(xyz.y);
    }
  });

  const Plane fy = apply_csf(yy, w, h, k.achromatic);
  const Plane fx = apply_csf(cx, w, h, k.red_green);
  const Plane fz = apply_csf(cz, w, h, k.blue_yellow);

  Prepared p;
  p.l.resize(n);
  p.a.resize(n);
  p.b.resize(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const double y = (fy[i] + 16.0) / 116.0;
      const glm::dvec3 xyz = glm::dvec3(y + fx[i] / 500.0, y, y - fz[i] / 200.0) * cs.white;
      // Filtering can leave the RGB cube; FLIP 2020 clamps to it before the perceptual transform.
      const glm::dvec3 rgb = glm::clamp(mul(cs.xyz_to_rgb, xyz), glm::dvec3(0.0), glm::dvec3(1.0));
      const glm::dvec3 lab = hunt_lab(rgb);
      p.l[i] = static_cast<float>(lab.x);
      p.a[i] = static_cast<float>(lab.y);
      p.b[i] = static_cast<float>(lab.z);
    }
  });

  const FeatureKernels& fk = k.feature;
  Plane hor(n), ex(n), ey(n), px(n), py(n);
  filter_rows(achromatic, hor, w, h, fk.edge);
  filter_cols(hor, ex, w, h, fk.gauss);
  filter_rows(achromatic, hor, w, h, fk.point);
  filter_cols(hor, px, w, h, fk.gauss);
  filter_rows(achromatic, hor, w, h, fk.gauss);
  filter_cols(hor, ey, w, h, fk.edge);
  filter_cols(hor, py, w, h, fk.point);
  p.edge.resize(n);
  p.point.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    p.edge[i] = std::hypot(ex[i], ey[i]);
    p.point[i] = std::hypot(px[i], py[i]);
  }
  return p;
}

// Per pixel: deltaE = deltaE_c ^ (1 - deltaE_f) (FLIP 2020), so features raise the colour error towards 1
// where edges or points differ. Every step treats the two images alike and combines them through |.|
// and squared differences, so the result is symmetric in (test, reference) bit for bit.
void combine(const Prepared& t, const Prepared& r, double cmax, std::vector<float>& error, std::vector<float>* color,
             std::vector<float>* feature) {
  const std::size_t n = t.l.size();
  error.resize(n);
  if (color) color->resize(n);
  if (feature) feature->resize(n);
  const double inv_sqrt2 = 1.0 / std::numbers::sqrt2;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const double dist = std::abs(double(t.l[i]) - double(r.l[i])) +
                          std::hypot(double(t.a[i]) - double(r.a[i]), double(t.b[i]) - double(r.b[i]));
      const double ec = redistribute(std::pow(dist, kQc), cmax);
      const double df = std::max(std::abs(double(t.edge[i]) - double(r.edge[i])),
                                 std::abs(double(t.point[i]) - double(r.point[i])));
      // Unit-normalised lobes on values in [0, 1] keep each detector output in [-1, 1], so df <= sqrt(2).
      const double ef = std::min(1.0, std::pow(inv_sqrt2 * df, kQf));
      error[i] = static_cast<float>(std::pow(ec, 1.0 - ef));
      if (color) (*color)[i] = static_cast<float>(ec);
      if (feature) (*feature)[i] = static_cast<float>(ef);
    }
  });
}

double mean_of(const std::vector<float>& v) {
  double sum = 0.0;
  for (float e : v) sum += e;
  return sum / static_cast<double>(v.size());
}

// ---------------------------------------------------------------------------------------------------
// HDR-FLIP: tone mappers as rational polynomials y = (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5) of the
// exposed value x = 2^exposure * c, clamped to [0, 1] (HDR-FLIP 2021).

struct ToneCurve {
  double k0, k1, k2, k3, k4, k5;
};

// Narkowicz's fit of the ACES filmic curve, x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), with his
// 0.6 pre-exposure folded into the coefficients.
constexpr ToneCurve kAces{0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14};
// Reinhard x / (1 + x), for the exposure range; the operator itself divides by 1 + luminance.
constexpr ToneCurve kReinhard{0.0, 1.0, 0.0, 0.0, 1.0, 1.0};

// Hable's filmic curve (Uncharted 2) with A..F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30, white point
// W = 11.2 and exposure bias 2: ((x(Ax + CB) + DE) / (x(Ax + B) + DF) - E/F) / white(W) at 2x.
ToneCurve hable_curve() {
  constexpr double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30, W = 11.2, bias = 2.0;
  const double k0 = A * F - A * E, k1 = C * B * F - B * E, k3 = A * F, k4 = B * F, k5 = D * F * F;
  const double white = (k0 * W * W + k1 * W) / (k3 * W * W + k4 * W + k5);
  return {bias * bias * k0 / white, bias * k1 / white, 0.0, bias * bias * k3, bias * k4, k5};
}

ToneCurve tone_curve(FlipToneMapper tm) {
  switch (tm) {
    case FlipToneMapper::aces: return kAces;
    case FlipToneMapper::hable: return hable_curve();
    case FlipToneMapper::reinhard: return kReinhard;
  }
  throw std::invalid_argument("FLIP: unknown tone mapper");
}

double apply_curve(const ToneCurve& c, double x) {
  double y;
  if (x <= 1.0) {
    y = (c.k0 * x * x + c.k1 * x + c.k2) / (c.k3 * x * x + c.k4 * x + c.k5);
  } else {  // divided through by x^2, so very bright pixels cannot overflow
    const double u = 1.0 / x;
    y = (c.k0 + c.k1 * u + c.k2 * u * u) / (c.k3 + c.k4 * u + c.k5 * u * u);
  }
  return std::clamp(y, 0.0, 1.0);
}

// Luminance, the Y row of the RGB -> XYZ matrix (the authors' choice for the exposure range and the
// Reinhard operator; within 1e-4 of Rec. 709's rounded 0.2126, 0.7152, 0.0722).
double luma(const glm::dvec3& c) { return kRgbToXyz[1][0] * c.r + kRgbToXyz[1][1] * c.g + kRgbToXyz[1][2] * c.b; }

std::vector<glm::vec3> tone_map(const Image& img, FlipToneMapper tm, const ToneCurve& curve, double exposure) {
  const double scale = std::exp2(exposure);
  std::vector<glm::vec3> out(img.rgb.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, out.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const glm::dvec3 x = glm::max(glm::dvec3(img.rgb[i]), glm::dvec3(0.0)) * scale;
      glm::dvec3 y;
      if (tm == FlipToneMapper::reinhard) {
        y = glm::clamp(x / (1.0 + luma(x)), glm::dvec3(0.0), glm::dvec3(1.0));
      } else {
        y = {apply_curve(curve, x.r), apply_curve(curve, x.g), apply_curve(curve, x.b)};
      }
      out[i] = glm::vec3(y);
    }
  });
  return out;
}

// The exposed value x that the curve maps to t: the positive root of (k0 - t k3) x^2 + (k1 - t k4) x +
// (k2 - t k5) = 0.
double exposed_value_for(const ToneCurve& c, double t) {
  const double qa = c.k0 - t * c.k3, qb = c.k1 - t * c.k4, qc = c.k2 - t * c.k5;
  if (qa == 0.0) return -qc / qb;
  return (-qb + std::sqrt(qb * qb - 4.0 * qa * qc)) / (2.0 * qa);
}

// The median as the authors take it (numpy's 50th percentile): the mean of the two middle values for an
// even count. `v` is reordered; it must not be empty.
double median_of(std::vector<double>& v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2 != 0) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
}

void check_exposure(double e, const char* what) {
  if (!std::isfinite(e) || std::abs(e) > kFlipMaxAbsExposure) {
    std::ostringstream os;
    os << "FLIP: " << what << " exposure must be finite and within +-" << kFlipMaxAbsExposure << ", got " << e;
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

double flip_pixels_per_degree(double distance_m, double display_width_m, int display_width_px) {
  if (!std::isfinite(distance_m) || distance_m <= 0.0 || !std::isfinite(display_width_m) || display_width_m <= 0.0 ||
      display_width_px <= 0) {
    std::ostringstream os;
    os << "FLIP: viewing distance, display width and display resolution must be positive, got " << distance_m
       << " m, " << display_width_m << " m, " << display_width_px << " px";
    throw std::invalid_argument(os.str());
  }
  return distance_m * (display_width_px / display_width_m) * kPi / 180.0;
}

FlipResult flip_ldr(const Image& test, const Image& reference, const FlipOptions& opt) {
  check_pair(test, reference, true);
  check_ppd(opt.ppd);
  const int w = test.width, h = test.height;
  const Kernels k = make_kernels(opt.ppd);
  auto decode = [](const Image& img) {
    std::vector<glm::vec3> lin(img.rgb.size());
    for (std::size_t i = 0; i < lin.size(); ++i)
      for (int c = 0; c < 3; ++c) lin[i][c] = static_cast<float>(srgb_to_linear(img.rgb[i][c]));
    return lin;
  };
  const Prepared pt = prepare(decode(test), w, h, k);
  const Prepared pr = prepare(decode(reference), w, h, k);
  FlipResult res;
  res.width = w;
  res.height = h;
  combine(pt, pr, k.cmax, res.error, opt.keep_terms ? &res.color_term : nullptr,
          opt.keep_terms ? &res.feature_term : nullptr);
  res.mean = mean_of(res.error);
  return res;
}

FlipResult flip_hdr(const Image& test, const Image& reference, const FlipOptions& opt) {
  check_pair(test, reference, false);
  check_ppd(opt.ppd);
  if (opt.num_exposures < 0 || opt.num_exposures > kFlipMaxExposures)
    throw std::invalid_argument("FLIP: num_exposures must be in [0, " + std::to_string(kFlipMaxExposures) +
                                "] (0 = automatic), got " + std::to_string(opt.num_exposures));
  if (opt.start_exposure) check_exposure(*opt.start_exposure, "start");
  if (opt.stop_exposure) check_exposure(*opt.stop_exposure, "stop");
  const int w = test.width, h = test.height;
  const ToneCurve curve = tone_curve(opt.tone_mapper);

  // HDR-FLIP 2021: start where the reference's brightest luminance tone-maps to 0.85, stop where its
  // median does, so the exposures cover the highlights down to the typical content.
  double start = 0.0, stop = 0.0;
  bool res_stop_from_positive = false;
  if (!opt.start_exposure || !opt.stop_exposure) {
    std::vector<double> lum(reference.rgb.size());
    for (std::size_t i = 0; i < lum.size(); ++i) lum[i] = luma(glm::max(glm::dvec3(reference.rgb[i]), glm::dvec3(0.0)));
    const double ymax = *std::max_element(lum.begin(), lum.end());
    double median = median_of(lum);
    const double x = exposed_value_for(curve, kExposureTarget);
    // A black reference has no range; the authors' implementation uses exposure 0 for both ends.
    if (ymax > 0.0) {
      start = std::log2(x / ymax);
      if (!opt.stop_exposure) {
        if (median <= 0.0 && opt.positive_median_fallback) {
          std::vector<double> positive;
          for (double v : lum)
            if (v > 0.0) positive.push_back(v);
          median = median_of(positive);
          res_stop_from_positive = true;
        }
        if (median <= 0.0)
          throw std::invalid_argument(
              "FLIP: the reference image's median luminance is 0 (at least half its pixels are black), so "
              "HDR-FLIP's automatic stop exposure log2(x / median) is infinite; give a stop exposure or allow "
              "the median of the non-black pixels");
        stop = std::log2(x / median);
      }
    }
  }
  if (opt.start_exposure) start = *opt.start_exposure;
  if (opt.stop_exposure) stop = *opt.stop_exposure;
  check_exposure(start, "start");
  check_exposure(stop, "stop");
  if (start > stop) {
    std::ostringstream os;
    os << "FLIP: start exposure " << start << " is above stop exposure " << stop;
    throw std::invalid_argument(os.str());
  }
  const int count = opt.num_exposures > 0 ? opt.num_exposures
                                          : std::max(2, static_cast<int>(std::ceil(stop - start)));
  const double step = (stop - start) / std::max(count - 1, 1);

  const Kernels k = make_kernels(opt.ppd);
  FlipResult res;
  res.width = w;
  res.height = h;
  res.start_exposure = start;
  res.stop_exposure = stop;
  res.stop_from_positive_median = res_stop_from_positive;
  res.error.assign(test.rgb.size(), 0.0f);
  std::vector<float> ldr;
  for (int i = 0; i < count; ++i) {
    const double exposure = start + i * step;
    res.exposures.push_back(exposure);
    // The authors sRGB-encode the tone-mapped images and LDR-FLIP decodes them again; that round trip is
    // the identity, so the linear tone-mapped values go straight in.
    const Prepared pt = prepare(tone_map(test, opt.tone_mapper, curve, exposure), w, h, k);
    const Prepared pr = prepare(tone_map(reference, opt.tone_mapper, curve, exposure), w, h, k);
    combine(pt, pr, k.cmax, ldr, nullptr, nullptr);
    for (std::size_t p = 0; p < ldr.size(); ++p) res.error[p] = std::max(res.error[p], ldr[p]);
  }
  res.mean = mean_of(res.error);
  return res;
}

double flip_mean(const FlipResult& r, const Mask& mask) {
  if (mask.on.empty()) return r.mean;
  if (mask.width != r.width || mask.height != r.height || mask.on.size() != r.error.size())
    throw std::invalid_argument("FLIP: the mask is " + size_str(mask.width, mask.height) + ", the error map " +
                                size_str(r.width, r.height));
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < mask.on.size(); ++i)
    if (mask.on[i]) {
      sum += r.error[i];
      ++n;
    }
  if (n == 0) throw std::invalid_argument("FLIP: the mask selects no pixels");
  return sum / static_cast<double>(n);
}

Image flip_error_map(const FlipResult& r) {
  // Eleven entries of matplotlib's 256-entry magma table (indices 0, 25, 51, 76, 102, 128, 153, 179, 204,
  // 230, 255, at t = index / 255), interpolated linearly: the map FLIP's authors publish their error
  // images in, so figures read the same as theirs.
  struct Stop {
    float t;
    glm::vec3 c;
  };
  static const std::array<Stop, 11> kMagma = {{{0.0f, {0.001462f, 0.000466f, 0.013866f}},
                                              {25.0f / 255.0f, {0.078815f, 0.054184f, 0.211667f}},
                                              {51.0f / 255.0f, {0.232077f, 0.059889f, 0.437695f}},
                                              {76.0f / 255.0f, {0.390384f, 0.100379f, 0.501864f}},
                                              {102.0f / 255.0f, {0.550287f, 0.161158f, 0.505719f}},
                                              {128.0f / 255.0f, {0.716387f, 0.214982f, 0.475290f}},
                                              {153.0f / 255.0f, {0.868793f, 0.287728f, 0.409303f}},
                                              {179.0f / 255.0f, {0.967671f, 0.439703f, 0.359810f}},
                                              {204.0f / 255.0f, {0.994738f, 0.624350f, 0.427397f}},
                                              {230.0f / 255.0f, {0.995680f, 0.812706f, 0.572645f}},
                                              {1.0f, {0.987053f, 0.991438f, 0.749504f}}}};
  Image out(r.width, r.height);
  for (std::size_t i = 0; i < r.error.size(); ++i) {
    const float t = std::clamp(r.error[i], 0.0f, 1.0f);
    std::size_t k = 0;
    while (k + 2 < kMagma.size() && t > kMagma[k + 1].t) ++k;
    const float f = (t - kMagma[k].t) / (kMagma[k + 1].t - kMagma[k].t);
    out.rgb[i] = kMagma[k].c * (1.0f - f) + kMagma[k + 1].c * f;
  }
  return out;
}

}  // namespace softgi::metrics
