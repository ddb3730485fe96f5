// Upsampling of receiver-buffer results to display resolution: paper 000 ("image-space
// accumulation"), section 4.2, eq. 11 (bilateral weights), and plain bilinear for comparison
// (the paper's Figure 7).
#include "softgi/render/frame_pool.hpp"
#include "upsample.hpp"
#include "tap_pack.hpp"

#include "softgi/render/gbuffer.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace softgi::techniques::common {

const char* to_string(UpsampleMode m) {
  switch (m) {
    case UpsampleMode::Bilateral: return "bilateral";
    case UpsampleMode::Bilinear: return "bilinear";
  }
  return "unknown";
}

UpsampleMode parse_upsample_mode(const std::string& s) {
  if (s == "bilateral") return UpsampleMode::Bilateral;
  if (s == "bilinear") return UpsampleMode::Bilinear;
  throw std::invalid_argument("unknown upsample mode '" + s + "' (expected bilateral or bilinear)");
}

const char* to_string(UpsampleFallback f) {
  switch (f) {
    case UpsampleFallback::Robust: return "robust";
    case UpsampleFallback::Shaded: return "shaded";
    case UpsampleFallback::None: return "none";
  }
  return "unknown";
}

UpsampleFallback parse_upsample_fallback(const std::string& s) {
  if (s == "robust") return UpsampleFallback::Robust;
  if (s == "shaded") return UpsampleFallback::Shaded;
  if (s == "none") return UpsampleFallback::None;
  throw std::invalid_argument("unknown upsample fallback '" + s + "' (expected robust, shaded or none)");
}

PlaneView plane_view(const render::GBuffer& g) {
  PlaneView v;
  v.width = g.width;
  v.height = g.height;
  v.scale = g.scale;
  v.depth = g.depth.data();
  v.normal = g.normal.data();
  return v;
}

bool upsample_sample_ok(const PlaneView& v, std::size_t i) {
  const float z = v.depth[i];
  if (z == std::numeric_limits<float>::infinity()) return true;
  if (!(z > 0.0f && std::isfinite(z))) return false;
  const glm::vec3 n = v.normal[i];
  return std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z);
}

std::string upsample_sample_error(const PlaneView& v, const char* name, int x, int y) {
  const std::size_t i = static_cast<std::size_t>(y) * v.width + x;
  const float z = v.depth[i];
  const bool background = std::isinf(z) && z > 0.0f;
  if (!background && !(std::isfinite(z) && z > 0.0f))
    return std::string(name) + " depth at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + std::to_string(z) +
           "; expected a positive eye-space depth or +inf for background";
  if (!background) {
    const glm::vec3 n = v.normal[i];
    if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z)))
      return std::string(name) + " normal at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is not finite";
  }
  return {};
}

std::size_t UpsampleWeights::bytes() const {
  return index.size() * sizeof(index[0]) + weight.size() * sizeof(weight[0]) + miss.size() * sizeof(miss[0]);
}

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("upsample: " + what); }

std::string dims(const PlaneView& v) {
  return std::to_string(v.width) + "x" + std::to_string(v.height) + " (scale " + std::to_string(v.scale) + ")";
}

void check_plane(const PlaneView& v, const char* name) {
  if (v.width <= 0 || v.height <= 0) fail(std::string(name) + " buffer size " + dims(v) + " must be positive");
  if (v.scale < 1) fail(std::string(name) + " buffer scale " + std::to_string(v.scale) + " must be at least 1");
  // Sample indices are int32 (UpsampleWeights::index).
  if (static_cast<std::int64_t>(v.width) * v.height > std::numeric_limits<std::int32_t>::max())
    fail(std::string(name) + " buffer " + dims(v) + " has more pixels than an int32 index can address");
  if (v.depth == nullptr) fail(std::string(name) + " buffer depth pointer is null");
  if (v.normal == nullptr) fail(std::string(name) + " buffer normal pointer is null");
}

// Depth must be a positive eye-space depth, or +inf for background; a hit needs a finite normal.
void check_sample(const PlaneView& v, const char* name, int x, int y) {
  const std::string e = upsample_sample_error(v, name, x, y);
  if (!e.empty()) fail(e);
}

void check_pair(const PlaneView& coarse, const PlaneView& fine) {
  check_plane(coarse, "coarse");
  check_plane(fine, "fine");
  if (fine.scale > coarse.scale)
    fail("fine buffer scale " + std::to_string(fine.scale) + " exceeds coarse buffer scale " + std::to_string(coarse.scale));
  // Both buffers cover the same display rectangle up to the rounding of the coarse size (floor or
  // ceil of display size / scale): their display extents differ by less than one coarse pixel.
  const auto extent_ok = [&](int fn, int cn) {
    const std::int64_t d = static_cast<std::int64_t>(fn) * fine.scale - static_cast<std::int64_t>(cn) * coarse.scale;
    return (d < 0 ? -d : d) < coarse.scale;
  };
  if (!extent_ok(fine.width, coarse.width) || !extent_ok(fine.height, coarse.height))
    fail("fine buffer " + dims(fine) + " and coarse buffer " + dims(coarse) +
         " do not cover the same display area (extents differ by a coarse pixel or more)");
  for (int y = 0; y < coarse.height; ++y)
    for (int x = 0; x < coarse.width; ++x) check_sample(coarse, "coarse", x, y);
}

void check_options(const UpsampleOptions& opt) {
  if (opt.mode != UpsampleMode::Bilateral && opt.mode != UpsampleMode::Bilinear)
    fail("unknown mode value " + std::to_string(static_cast<int>(opt.mode)));
  if (!std::isfinite(opt.epsilon_rel) || !(opt.epsilon_rel > 0.0))
    fail("epsilon_rel = " + std::to_string(opt.epsilon_rel) + " must be finite and positive");
  if (opt.normal_power < 0) fail("normal_power = " + std::to_string(opt.normal_power) + " must not be negative");
  if (!std::isfinite(opt.miss_threshold) || opt.miss_threshold < 0.0)
    fail("miss_threshold = " + std::to_string(opt.miss_threshold) + " must be finite and not negative");
}

bool is_hit(float z) { return z < std::numeric_limits<float>::infinity(); }

// b^e for e >= 0 by squaring (std::pow per sample would dominate the pass); 0^0 = 1, so
// normal_power 0 switches the normal weight off.
float ipow(float b, int e) {
  float r = 1.0f;
  while (e > 0) {
    if (e & 1) r *= b;
    b *= b;
    e >>= 1;
  }
  return r;
}

// One axis of the bilinear footprint: coarse coordinate u (pixel centres at integers) clamped to
// the buffer, so that the border behaves as clamp-to-edge; i1 = i0 + 1 except for a buffer one
// pixel wide, where f = 0 makes the second tap vanish.
struct Axis {
  int i0, i1;
  double f;
};
Axis axis(double u, int n) {
  u = std::clamp(u, 0.0, static_cast<double>(n - 1));
  const int i0 = std::min(static_cast<int>(std::floor(u)), std::max(n - 2, 0));
  return {i0, std::min(i0 + 1, n - 1), u - i0};
}

struct Block {
  int n = 0;
  std::array<std::int32_t, 4> idx{};
  std::array<double, 4> w{};  // bilinear weights w_b, all > 0
  std::array<float, 4> wf{};  // the same as eq. 11 takes them: the float product of the float axis weights
};

// The eq. 11 kernel works in float, as the Vulkan shader does: its weights are stored as float,
// and float halves the vector work of the double it used before (bench_gbuffer's
// BM_Upsample/<scene>/weights). The axis weights in float: 1 - f and f, each rounded once.
float left_weight(double f) { return static_cast<float>(1.0 - f); }
float right_weight(double f) { return static_cast<float>(f); }

// The bilinear footprints of every display column and row: they depend on X or Y alone, so a pass
// over the display works them out once per column and row instead of once per pixel. The columns'
// are kept as streams (left column, right column, right weight f) for bilateral_run's vector loops;
// column(X) puts one together for the per-pixel paths.
struct Footprints {
  std::vector<std::int32_t> x_i0, x_i1;
  std::vector<double> x_f;
  std::vector<float> x_left, x_right;  // left_weight and right_weight of x_f, for the float kernel
  std::vector<Axis> y;
  Footprints(const PlaneView& c, const PlaneView& f)
      : x_i0(f.width), x_i1(f.width), x_f(f.width), x_left(f.width), x_right(f.width), y(f.height) {
    const double ratio = static_cast<double>(f.scale) / static_cast<double>(c.scale);
    for (int X = 0; X < f.width; ++X) {
      const Axis a = axis((X + 0.5) * ratio - 0.5, c.width);
      x_i0[X] = a.i0;
      x_i1[X] = a.i1;
      x_f[X] = a.f;
      x_left[X] = left_weight(a.f);
      x_right[X] = right_weight(a.f);
    }
    for (int Y = 0; Y < f.height; ++Y) y[Y] = axis((Y + 0.5) * ratio - 0.5, c.height);
  }
  Axis column(int X) const { return {x_i0[X], x_i1[X], x_f[X]}; }
};

// One coarse row's depth and normal at the left and right tap column of every display column:
// the coarse samples that bilateral_run reads, laid out as streams, so that its loops load instead of
// gathering. A coarse row serves the display rows of two block rows (about 2 scale of them), so a
// run of display rows expands each once.
struct ExpandedRow {
  int row = -1;
  std::vector<float> z[2], nx[2], ny[2], nz[2];  // [0]: left tap column, [1]: right
  void expand(const PlaneView& c, const Footprints& fp, int coarse_row) {
    row = coarse_row;
    const std::size_t w = fp.x_i0.size();
    for (int side = 0; side < 2; ++side) {
      z[side].resize(w);
      nx[side].resize(w);
      ny[side].resize(w);
      nz[side].resize(w);
      const std::int32_t* col = side == 0 ? fp.x_i0.data() : fp.x_i1.data();
      for (std::size_t X = 0; X < w; ++X) {
        const std::size_t i = static_cast<std::size_t>(coarse_row) * c.width + col[X];
        z[side][X] = c.depth[i];
        nx[side][X] = c.normal[i].x;
        ny[side][X] = c.normal[i].y;
        nz[side][X] = c.normal[i].z;
      }
    }
  }
};

// The 2x2 coarse block of display pixel (X, Y): its centre X + 0.5 (in fine pixels of size
// fine.scale) is the display point (X + 0.5) fine.scale, i.e. coarse coordinate
// (X + 0.5) fine.scale / coarse.scale - 0.5 (Footprints). Taps with w_b = 0 are dropped, so that a
// pixel sitting exactly on a coarse centre takes that sample alone (scale 1 is the identity).
Block bilinear_block(const PlaneView& c, const Axis& ax, const Axis& ay) {
  const int xs[2] = {ax.i0, ax.i1}, ys[2] = {ay.i0, ay.i1};
  const double wx[2] = {1.0 - ax.f, ax.f}, wy[2] = {1.0 - ay.f, ay.f};
  const float fx[2] = {left_weight(ax.f), right_weight(ax.f)}, fy[2] = {left_weight(ay.f), right_weight(ay.f)};
  Block b;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const double w = wx[i] * wy[j];
      if (w > 0.0) {
        b.idx[b.n] = static_cast<std::int32_t>(ys[j] * c.width + xs[i]);
        b.w[b.n] = w;
        b.wf[b.n] = fx[i] * fy[j];
        ++b.n;
      }
    }
  return b;
}

struct Pixel {
  std::array<std::int32_t, 4> idx{-1, -1, -1, -1};
  std::array<float, 4> w{0.0f, 0.0f, 0.0f, 0.0f};
  bool miss = false;
};

// Keeps the taps with positive weight, normalised; false when there is none.
bool store_normalised(const Block& b, const std::array<double, 4>& w, Pixel& out) {
  double sum = 0.0;
  for (int k = 0; k < b.n; ++k) sum += w[k];
  if (!(sum > 0.0)) return false;
  int m = 0;
  for (int k = 0; k < b.n; ++k)
    if (w[k] > 0.0) {
      out.idx[m] = b.idx[k];
      out.w[m] = static_cast<float>(w[k] / sum);
      ++m;
    }
  return true;
}

// Plain bilinear over the valid (hit) coarse taps.
bool bilinear_valid(const PlaneView& c, const Block& b, Pixel& out) {
  std::array<double, 4> w{};
  for (int k = 0; k < b.n; ++k) w[k] = is_hit(c.depth[b.idx[k]]) ? b.w[k] : 0.0;
  return store_normalised(b, w, out);
}

// Display pixel p, whose column and row have the footprints ax and ay.
Pixel upsample_pixel(const PlaneView& c, const PlaneView& f, const UpsampleOptions& opt, std::size_t p, const Axis& ax,
                     const Axis& ay) {
  Pixel out;
  const float zp = f.depth[p];
  if (!is_hit(zp)) return out;  // background: nothing to shade, not a miss
  const Block b = bilinear_block(c, ax, ay);
  if (opt.mode == UpsampleMode::Bilinear) {
    out.miss = !bilinear_valid(c, b, out);
    return out;
  }
  // Eq. 11: w~_i = w_b,i w_z,i w_N,i with w_z = 1 / (eps + |z_p - z_i|), w_N = max(0, N_p . N_i)^32.
  // We use eps w_z = eps / (eps + |z_p - z_i|) in (0, 1] instead: the constant factor eps cancels
  // in the normalisation, the sum is then directly the miss measure of UpsampleOptions (1 for a
  // perfect match), and nothing overflows for tiny eps. In float, each operation in the order
  // bilateral_run takes it (that file's -ffp-contract=off keeps them apart).
  const float eps = static_cast<float>(opt.epsilon_rel) * zp;
  const glm::vec3 np = f.normal[p];
  std::array<float, 4> w{};
  float measure = 0.0f;
  for (int k = 0; k < b.n; ++k) {
    const float zi = c.depth[b.idx[k]];
    if (!is_hit(zi)) continue;  // background coarse sample: weight 0
    const float wz = eps / (eps + std::abs(zp - zi));
    const glm::vec3 ni = c.normal[b.idx[k]];
    const float d = np.x * ni.x + np.y * ni.y + np.z * ni.z;
    const float wn = ipow(d > 0.0f ? d : 0.0f, opt.normal_power);
    w[k] = b.wf[k] * wz * wn;
    measure += w[k];
  }
  if (measure > 0.0f) {
    int m = 0;
    for (int k = 0; k < b.n; ++k)
      if (w[k] > 0.0f) {
        out.idx[m] = b.idx[k];
        out.w[m] = w[k] / measure;
        ++m;
      }
    out.miss = measure < static_cast<float>(opt.miss_threshold);
    return out;
  }
  // Every eq. 11 weight vanished (all taps background or facing away): bilinear over the valid
  // taps still gives the pixel a value; it is a miss either way (section 4.2's fallbacks apply).
  bilinear_valid(c, b, out);
  out.miss = true;
  return out;
}

// Eq. 11 for a run of at most kRun display pixels of one row (the bilateral mode): the same
// weights, bits included, as upsample_pixel, written as passes over the run (tap weights without
// the normal power, the power by squaring, sums and normalisation, the packing) so that they
// vectorise, with the coarse samples of the row's two tap rows from `rows` (ExpandedRow) instead of
// gathered. Compiled for AVX-512, AVX2 and the baseline (target_clones; -ffp-contract=off for this
// file keeps every version's bits those of the baseline). Also checks the run's display samples
// (upsample_sample_ok): false where one is bad, and the caller names it.
constexpr int kRun = 64;

__attribute__((target_clones("avx512f", "avx2", "default"))) bool bilateral_run(
    const PlaneView& c, const PlaneView& f, const UpsampleOptions& opt, const Footprints& fp, const ExpandedRow* const rows[2],
    int y, int x0, int n, std::array<std::int32_t, 4>* __restrict out_idx, std::array<float, 4>* __restrict out_w,
    std::uint8_t* __restrict out_miss) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const Axis& ay = fp.y[y];
  const std::size_t row0 = static_cast<std::size_t>(y) * f.width;
  const int ys[2] = {ay.i0, ay.i1};
  const float wy[2] = {left_weight(ay.f), right_weight(ay.f)};
  // Tap k of pixel t at [k * n + t]: flat runs, so that every loop below is one stream.
  alignas(64) float wbz[4 * kRun];   // w_b eps w_z, 0 for a background tap or one with w_b = 0
  alignas(64) float base[4 * kRun];  // max(0, N_p . N_i)
  alignas(64) float wn[4 * kRun];    // base^normal_power, then the eq. 11 weight
  alignas(64) std::int32_t tap[4 * kRun];
  const float* __restrict fz = f.depth + row0 + x0;
  const glm::vec3* __restrict fn = f.normal + row0 + x0;
  const float eps_rel = static_cast<float>(opt.epsilon_rel);
  // upsample_sample_ok over the run: a background depth, or a positive finite one with a finite normal.
  int bad = 0;
  for (int t = 0; t < n; ++t) {
    const float z = fz[t];
    const bool finite_n = (std::abs(fn[t].x) < kInf) & (std::abs(fn[t].y) < kInf) & (std::abs(fn[t].z) < kInf);
    const bool ok = (z == kInf) | ((z > 0.0f) & (z < kInf) & finite_n);
    bad |= ok ? 0 : 1;
  }
  if (bad) return false;
  // One tap column (left or right: a constant, so that the loop has no branch) of one tap row.
  const auto taps = [&](auto right, int k) {
    const int j = k >> 1, side = right ? 1 : 0;
    const std::int32_t crow = ys[j] * c.width;
    const float wyj = wy[j];
    const ExpandedRow& er = *rows[j];
    const float* __restrict cz = er.z[side].data() + x0;
    const float* __restrict cnx = er.nx[side].data() + x0;
    const float* __restrict cny = er.ny[side].data() + x0;
    const float* __restrict cnz = er.nz[side].data() + x0;
    const float* __restrict wx = (right ? fp.x_right.data() : fp.x_left.data()) + x0;
    const std::int32_t* __restrict col = (right ? fp.x_i1.data() : fp.x_i0.data()) + x0;
    float* __restrict wbz_k = wbz + k * n;
    float* __restrict base_k = base + k * n;
    std::int32_t* __restrict tap_k = tap + k * n;
    for (int t = 0; t < n; ++t) {
      const float wb = wx[t] * wyj;
      const float zp = fz[t], zi = cz[t];
      const float eps = eps_rel * zp;
      const float wz = eps / (eps + std::abs(zp - zi));
      const float d = fn[t].x * cnx[t] + fn[t].y * cny[t] + fn[t].z * cnz[t];
      tap_k[t] = crow + col[t];
      const bool live = (wb > 0.0f) & (zi < kInf);
      wbz_k[t] = live ? wb * wz : 0.0f;
      base_k[t] = d > 0.0f ? d : 0.0f;
    }
  };
  for (int j = 0; j < 2; ++j) {
    taps(std::false_type{}, 2 * j);
    taps(std::true_type{}, 2 * j + 1);
  }
  // ipow across the run: the exponent's bits are the same for every pixel. One pass over the run
  // per bit; the last bit needs no further square.
  const int m4 = 4 * n;
  for (int t = 0; t < m4; ++t) wn[t] = 1.0f;
  for (int e = opt.normal_power; e > 0; e >>= 1) {
    if ((e & 1) && e > 1) {
      for (int t = 0; t < m4; ++t) {
        wn[t] *= base[t];
        base[t] *= base[t];
      }
    } else if (e & 1) {
      for (int t = 0; t < m4; ++t) wn[t] *= base[t];
    } else {
      for (int t = 0; t < m4; ++t) base[t] *= base[t];
    }
  }
  // The eq. 11 weights, their sum (the miss measure) and the normalised weights, across the run.
  // A background tap's normal may be anything: its weight is 0 whatever its power.
  alignas(64) float measure[kRun];
  alignas(64) float wf[4 * kRun];
  for (int t = 0; t < m4; ++t) wn[t] = wbz[t] > 0.0f ? wbz[t] * wn[t] : 0.0f;
  for (int t = 0; t < n; ++t) measure[t] = 0.0f;
  for (int k = 0; k < 4; ++k)
    for (int t = 0; t < n; ++t) measure[t] += wn[k * n + t];
  for (int k = 0; k < 4; ++k)
    for (int t = 0; t < n; ++t) wf[k * n + t] = wn[k * n + t] / measure[t];  // used where measure > 0
  // The taps with positive weight, packed to the front in tap order (detail::pack_taps). A
  // background pixel has none (its eps is infinite, so w_z is NaN and every wn is 0), and so gets
  // -1 and 0 in every slot, as upsample_pixel leaves it.
  detail::pack_taps(tap, wf, wn, n, n, out_idx, out_w);
  const float threshold = static_cast<float>(opt.miss_threshold);
  // The misses, and whether any display sample (checked above: +inf or finite) lost every weight.
  int fallback = 0;
  for (int t = 0; t < n; ++t) {
    const bool weighted = measure[t] > 0.0f;
    out_miss[t] = weighted & (measure[t] < threshold) ? 1 : 0;
    fallback |= (fz[t] < kInf) & !weighted;
  }
  for (int t = 0; fallback && t < n; ++t) {
    if (!is_hit(fz[t]) || measure[t] > 0.0f) continue;
    // Every eq. 11 weight vanished: upsample_pixel's bilinear fallback, rare.
    const Pixel px = upsample_pixel(c, f, opt, row0 + static_cast<std::size_t>(x0 + t), fp.column(x0 + t), ay);
    out_idx[t] = px.idx;
    out_w[t] = px.w;
    out_miss[t] = px.miss ? 1 : 0;
  }
  return true;
}

void check_weights(const UpsampleWeights& w) {
  const std::size_t n = static_cast<std::size_t>(std::max(w.width, 0)) * static_cast<std::size_t>(std::max(w.height, 0));
  if (w.width <= 0 || w.height <= 0 || w.index.size() != n || w.weight.size() != n || w.miss.size() != n)
    fail("weights of " + std::to_string(w.width) + "x" + std::to_string(w.height) +
         " pixels have inconsistent array sizes (index " + std::to_string(w.index.size()) + ", weight " +
         std::to_string(w.weight.size()) + ", miss " + std::to_string(w.miss.size()) + ")");
}

void check_io(const float* in, int channels, const float* out) {
  if (in == nullptr) fail("input pointer is null");
  if (out == nullptr) fail("output pointer is null");
  if (channels < 1) fail("channels = " + std::to_string(channels) + " must be at least 1");
}

}  // namespace

UpsampleWeights upsample_weights(const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt,
                                 render::FramePool* pool) {
  check_options(opt);
  check_pair(coarse, fine);
  UpsampleWeights r;
  r.width = fine.width;
  r.height = fine.height;
  const std::size_t n = static_cast<std::size_t>(fine.width) * fine.height;
  // Every pixel's entries are written below.
  if (pool) {
    r.index = pool->take_for_overwrite<std::array<std::int32_t, 4>>(n);
    r.weight = pool->take_for_overwrite<std::array<float, 4>>(n);
    r.miss = pool->take_for_overwrite<std::uint8_t>(n);
  } else {
    r.index.resize(n);
    r.weight.resize(n);
    r.miss.resize(n);
  }
  const Footprints fp(coarse, fine);
  // Runs of display rows, so that each task expands a coarse row once for the rows it serves.
  constexpr int kRowsPerTask = 16;
  tbb::parallel_for(tbb::blocked_range<int>(0, fine.height, kRowsPerTask), [&](const tbb::blocked_range<int>& rows) {
    ExpandedRow expanded[2];
    for (int y = rows.begin(); y != rows.end(); ++y) {
      const std::size_t row0 = static_cast<std::size_t>(y) * fine.width;
      // A bad display sample throws (check_sample names it); TBB rethrows it in the calling thread.
      const auto check_row = [&] {
        for (int x = 0; x < fine.width; ++x)
          if (!upsample_sample_ok(fine, row0 + x)) check_sample(fine, "fine", x, y);
      };
      if (opt.mode == UpsampleMode::Bilateral) {
        // The two coarse rows of this display row's blocks, expanded unless a slot holds them.
        const int need[2] = {fp.y[y].i0, fp.y[y].i1};
        const auto held = [&](int row) -> ExpandedRow* {
          for (ExpandedRow& e : expanded)
            if (e.row == row) return &e;
          return nullptr;
        };
        const auto other = [&](const ExpandedRow* e) { return e == &expanded[0] ? &expanded[1] : &expanded[0]; };
        ExpandedRow* top = held(need[0]);
        ExpandedRow* bottom = held(need[1]);
        if (top == nullptr) {
          top = other(bottom);
          top->expand(coarse, fp, need[0]);
        }
        if (bottom == nullptr) {
          bottom = need[1] == need[0] ? top : other(top);
          if (bottom != top) bottom->expand(coarse, fp, need[1]);
        }
        const ExpandedRow* const tap_rows[2] = {top, bottom};
        for (int x0 = 0; x0 < fine.width; x0 += kRun) {
          const std::size_t p = row0 + x0;
          if (!bilateral_run(coarse, fine, opt, fp, tap_rows, y, x0, std::min(kRun, fine.width - x0), &r.index[p], &r.weight[p],
                             &r.miss[p]))
            check_row();
        }
        continue;
      }
      check_row();
      for (int x = 0; x < fine.width; ++x) {
        const std::size_t p = row0 + x;
        const Pixel px = upsample_pixel(coarse, fine, opt, p, fp.column(x), fp.y[y]);
        r.index[p] = px.idx;
        r.weight[p] = px.w;
        r.miss[p] = px.miss ? 1 : 0;
      }
    }
  });
  r.misses = static_cast<std::size_t>(std::count(r.miss.begin(), r.miss.end(), std::uint8_t{1}));
  return r;
}

void upsample_apply(const UpsampleWeights& w, const float* in, int channels, float* out) {
  check_weights(w);
  check_io(in, channels, out);
  // The channel count as a constant where it is 3 (indirect light) or 1, so that the per-tap loop
  // over channels is straight-line code.
  const auto rows_with = [&](auto channel_count) {
    const std::size_t ch = channel_count > 0 ? static_cast<std::size_t>(channel_count) : static_cast<std::size_t>(channels);
    tbb::parallel_for(tbb::blocked_range<int>(0, w.height), [&](const tbb::blocked_range<int>& rows) {
      for (int y = rows.begin(); y != rows.end(); ++y)
        for (int x = 0; x < w.width; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * w.width + x;
          const auto& idx = w.index[p];
          if (idx[0] < 0) continue;  // taps are packed to the front: no tap, pixel left untouched
          float* o = out + p * ch;
          for (std::size_t c = 0; c < ch; ++c) o[c] = 0.0f;
          for (int k = 0; k < 4 && idx[k] >= 0; ++k) {
            const float wk = w.weight[p][k];
            const float* s = in + static_cast<std::size_t>(idx[k]) * ch;
            for (std::size_t c = 0; c < ch; ++c) o[c] += wk * s[c];
          }
        }
    });
  };
  if (channels == 3)
    rows_with(std::integral_constant<int, 3>{});
  else if (channels == 1)
    rows_with(std::integral_constant<int, 1>{});
  else
    rows_with(std::integral_constant<int, 0>{});
}

void upsample_apply_bilinear(const UpsampleWeights& w, const PlaneView& coarse, const PlaneView& fine, const float* in,
                             int channels, float* out, const std::vector<std::uint8_t>* only) {
  check_weights(w);
  check_pair(coarse, fine);
  check_io(in, channels, out);
  if (w.width != fine.width || w.height != fine.height)
    fail("weights of " + std::to_string(w.width) + "x" + std::to_string(w.height) + " pixels do not match fine buffer " +
         dims(fine));
  if (only != nullptr && only->size() != w.miss.size())
    fail("pixel selection has " + std::to_string(only->size()) + " entries for " + std::to_string(w.miss.size()) +
         " pixels");
  const std::size_t ch = static_cast<std::size_t>(channels);
  const Footprints fp(coarse, fine);
  tbb::parallel_for(tbb::blocked_range<int>(0, fine.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y)
      for (int x = 0; x < fine.width; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * fine.width + x;
        if (only != nullptr && (*only)[p] == 0) continue;
        if (!upsample_sample_ok(fine, p)) check_sample(fine, "fine", x, y);
        if (!is_hit(fine.depth[p])) continue;
        Pixel px;
        if (!bilinear_valid(coarse, bilinear_block(coarse, fp.column(x), fp.y[y]), px)) continue;  // no valid tap
        float* o = out + p * ch;
        for (std::size_t c = 0; c < ch; ++c) o[c] = 0.0f;
        for (int k = 0; k < 4 && px.idx[k] >= 0; ++k) {
          const float* s = in + static_cast<std::size_t>(px.idx[k]) * ch;
          for (std::size_t c = 0; c < ch; ++c) o[c] += px.w[k] * s[c];
        }
      }
  });
}

UpsampleKernels cpu_upsample_kernels(render::FramePool* pool) {
  return {[pool](const PlaneView& c, const PlaneView& f, const UpsampleOptions& o) { return upsample_weights(c, f, o, pool); },
          upsample_apply};
}

void give(render::FramePool& pool, UpsampleWeights&& w) {
  pool.give(std::move(w.index));
  pool.give(std::move(w.weight));
  pool.give(std::move(w.miss));
  w = UpsampleWeights();
}

}  // namespace softgi::techniques::common
