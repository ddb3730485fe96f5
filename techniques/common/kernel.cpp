// The hot loop of SHEXP: log-visibility accumulation (paper 004 eqs. 8, 34, 38) vectorised across
// receivers. The kernel body (kernel_body.hpp) is compiled three times: for AVX-512 (16 lanes), for
// AVX2+FMA (8 lanes) and as portable scalar code; the build uses no -march flag, so the vector
// versions are compiled under `#pragma GCC target` and chosen at run time from the CPU's features.
// GCC 12 reports its own AVX-512 intrinsics (_mm512_undefined_ps self-initialisation) as maybe
// uninitialised once inlined (or, for the integer multiply and gathers, as uninitialised); the
// warning is about the compiler header, not this code.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <memory>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

#include "accumulation.hpp"
#include "softgi_shared.h"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::common {

namespace {

// Normalised associated-Legendre recurrence in z for the real basis of docs/sh.md (no
// Condon-Shortley phase): y_{l,0} = Q_l^0(z), y_{l,m} = Q_l^m(z) C_m, y_{l,-m} = Q_l^m(z) S_m with
// Q_l^m = N_lm P_l^m, P the associated Legendre polynomial without its (1 - z^2)^{m/2} factor
// (carried by C_m, S_m) and N_lm = K_l^m (times sqrt 2 for m > 0).
struct BasisConsts {
  float qmm[kMaxAccOrder] = {};                    // Q_m^m (a constant)
  float a1[kMaxAccOrder] = {};                     // Q_{m+1}^m = a1[m] z Q_m^m
  float A[kMaxAccOrder][kMaxAccOrder] = {};        // Q_l^m = A z Q_{l-1}^m - B Q_{l-2}^m, l >= m + 2
  float B[kMaxAccOrder][kMaxAccOrder] = {};
};

const BasisConsts& basis_consts() {
  static const BasisConsts c = [] {
    BasisConsts k;
    auto norm = [](int l, int m) {
      double ratio = 1.0;  // (l - m)! / (l + m)!
      for (int i = l - m + 1; i <= l + m; ++i) ratio /= i;
      double v = std::sqrt((2.0 * l + 1.0) / (4.0 * sh::kPi) * ratio);
      return m > 0 ? v * std::sqrt(2.0) : v;
    };
    for (int m = 0; m < kMaxAccOrder; ++m) {
      double pmm = 1.0;  // (2m - 1)!!
      for (int i = 1; i <= 2 * m - 1; i += 2) pmm *= i;
      k.qmm[m] = static_cast<float>(norm(m, m) * pmm);
      if (m + 1 < kMaxAccOrder) k.a1[m] = static_cast<float>(norm(m + 1, m) * (2.0 * m + 1.0) / norm(m, m));
      for (int l = m + 2; l < kMaxAccOrder; ++l) {
        k.A[l][m] = static_cast<float>((2.0 * l - 1.0) / (l - m) * norm(l, m) / norm(l - 1, m));
        k.B[l][m] = static_cast<float>((l + m - 1.0) / (l - m) * norm(l, m) / norm(l - 2, m));
      }
    }
    return k;
  }();
  return c;
}

// Flush-to-zero and denormals-are-zero for the calling thread while a kernel runs: log vectors of
// barely shadowed receivers have coefficients near 1e-20 whose squares and products are subnormal,
// and every subnormal operand or result costs a microcode assist (measured: exponentiation of the
// `spheres` scene 10x slower). Values below 1e-38 carry no information here.
class FlushDenormals {
 public:
  FlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | 0x8040u); }  // FTZ (bit 15) | DAZ (bit 6)
  ~FlushDenormals() { _mm_setcsr(saved_); }
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;

 private:
  unsigned saved_;
};

// Abramowitz & Stegun 4.4.46: asin x = pi/2 - sqrt(1 - x) sum a_i x^i on [0, 1].
constexpr float kAsin[8] = {1.5707963050f, -0.2145988016f, 0.0889789874f, -0.0501743046f,
                            0.0308918810f, -0.0170881256f, 0.0066700901f, -0.0012624911f};

}  // namespace

// The same constants for the Vulkan shaders (shexp_vulkan.cpp), in softgi_shared.h's layout.
std::vector<float> basis_recurrence_constants() {
  const BasisConsts& c = basis_consts();
  std::vector<float> v(gpu::kBasisFloats, 0.0f);
  static_assert(kMaxAccOrder == static_cast<int>(gpu::kAccumMaxOrder), "softgi_shared.h and accumulation.hpp disagree");
  for (int m = 0; m < kMaxAccOrder; ++m) {
    v[gpu::kBasisQmm + m] = c.qmm[m];
    v[gpu::kBasisA1 + m] = c.a1[m];
    for (int l = 0; l < kMaxAccOrder; ++l) {
      v[gpu::kBasisA + l * kMaxAccOrder + m] = c.A[l][m];
      v[gpu::kBasisB + l * kMaxAccOrder + m] = c.B[l][m];
    }
  }
  for (int k = 0; k < 8; ++k) v[gpu::kBasisAsin + k] = kAsin[k];
  return v;
}

// ---------------------------------------------------------------------------------------------
// Portable scalar version (also the reference the vector versions are tested against).
namespace kscalar {
struct Vec {
  using F = float;
  using I = int;
  using M = bool;
  static constexpr int W = 1;
  static F set(float x) { return x; }
  static F load(const float* p) { return *p; }
  static void store(float* p, F x) { *p = x; }
  // out[k W + l] = in[l stride + k] for a W x W block (here 1 x 1).
  static void transpose(const float* in, std::size_t, float* out) { out[0] = in[0]; }
  // out[l] = sum over i in [from, to) of x[i W + l]^2 in double, in order of i.
  static void sum_squares_double(const float* x, int from, int to, double* out) {
    double a = 0.0;
    for (int i = from; i < to; ++i) a += static_cast<double>(x[i]) * x[i];
    out[0] = a;
  }
  static F add(F a, F b) { return a + b; }
  static F sub(F a, F b) { return a - b; }
  static F mul(F a, F b) { return a * b; }
  static F div(F a, F b) { return a / b; }
  static F fma(F a, F b, F c) { return a * b + c; }
  static F fnma(F a, F b, F c) { return c - a * b; }
  static F min(F a, F b) { return a < b ? a : b; }
  static F max(F a, F b) { return a > b ? a : b; }
  static F sqrt(F a) { return std::sqrt(a); }
  static M lt(F a, F b) { return a < b; }
  static M ge(F a, F b) { return a >= b; }
  static F select(M m, F a, F b) { return m ? a : b; }
  static I trunc(F x) { return x > -2e9f && x < 2e9f ? static_cast<int>(x) : 0; }
  static F to_float(I i) { return static_cast<float>(i); }
  static I iclamp(I i, int lo, int hi) { return i < lo ? lo : (i > hi ? hi : i); }
  // base[i] per lane (i a valid index).
  static F gather(const float* base, I i) { return base[i]; }
  static I iload(const int* p) { return *p; }
  static I imul(I a, int k) { return a * k; }
  static F rsqrt(F a) { return 1.0f / std::sqrt(a); }
  static bool all(M m) { return m; }
  static bool any(M m) { return m; }
  static M land(M a, M b) { return a && b; }
  static int count(M m) { return m ? 1 : 0; }
  template <int N>
  static void fetch_bands(const ZhTable& t, I row, F fr, F* out) {
    const float* r = t.data.data() + static_cast<std::size_t>(row) * 2 * N;
    for (int l = 0; l < N; ++l) out[l] = fma(fr, r[2 * l + 1], r[2 * l]);
  }
};
#include "kernel_body.hpp"
#include "batch_body.hpp"
#include "proxy_light_body.hpp"
#include "fan_body.hpp"
}  // namespace kscalar

// ---------------------------------------------------------------------------------------------
// Counting version: the same code on a number type that counts its arithmetic.
namespace kcount {
thread_local double g_flops = 0.0;
struct Num {
  float v;
};
struct Vec {
  using F = Num;
  using I = int;
  using M = bool;
  static constexpr int W = 1;
  static F set(float x) { return {x}; }
  static F load(const float* p) { return {*p}; }
  static void store(float* p, F x) { *p = x.v; }
  static F add(F a, F b) { g_flops += 1; return {a.v + b.v}; }
  static F sub(F a, F b) { g_flops += 1; return {a.v - b.v}; }
  static F mul(F a, F b) { g_flops += 1; return {a.v * b.v}; }
  static F div(F a, F b) { g_flops += 1; return {a.v / b.v}; }
  static F fma(F a, F b, F c) { g_flops += 2; return {a.v * b.v + c.v}; }
  static F fnma(F a, F b, F c) { g_flops += 2; return {c.v - a.v * b.v}; }
  static F min(F a, F b) { return {a.v < b.v ? a.v : b.v}; }
  static F max(F a, F b) { return {a.v > b.v ? a.v : b.v}; }
  static F sqrt(F a) { g_flops += 1; return {std::sqrt(a.v)}; }
  static M lt(F a, F b) { return a.v < b.v; }
  static M ge(F a, F b) { return a.v >= b.v; }
  static F select(M m, F a, F b) { return m ? a : b; }
  static I trunc(F x) { return x.v > -2e9f && x.v < 2e9f ? static_cast<int>(x.v) : 0; }
  static F to_float(I i) { return {static_cast<float>(i)}; }
  static I iclamp(I i, int lo, int hi) { return i < lo ? lo : (i > hi ? hi : i); }
  // A refined reciprocal square root stands for the square root and division it replaces.
  static F rsqrt(F a) { g_flops += 2; return {1.0f / std::sqrt(a.v)}; }
  static bool all(M m) { return m; }
  static int count(M m) { return m ? 1 : 0; }
  template <int N>
  static void fetch_bands(const ZhTable& t, I row, F fr, F* out) {
    const float* r = t.data.data() + static_cast<std::size_t>(row) * 2 * N;
    for (int l = 0; l < N; ++l) out[l] = fma(fr, F{r[2 * l + 1]}, F{r[2 * l]});
  }
};
#include "kernel_body.hpp"
}  // namespace kcount

// ---------------------------------------------------------------------------------------------
// AVX2 + FMA, 8 lanes.
#pragma GCC push_options
#pragma GCC target("avx2,fma")
namespace kavx2 {
struct Vec {
  using F = __m256;
  using I = __m256i;
  using M = __m256;
  static constexpr int W = 8;
  static F set(float x) { return _mm256_set1_ps(x); }
  static F load(const float* p) { return _mm256_loadu_ps(p); }
  static void store(float* p, F x) { _mm256_storeu_ps(p, x); }
  // out[k W + l] = in[l stride + k], 8 x 8: pairs of rows interleaved, then 4 x 4 within each 128-bit
  // lane (u[4g + q] holds rows 4g..4g+3 of column 4L + q in lane L), then the lanes exchanged.
  static void transpose(const float* in, std::size_t stride, float* out) {
    F r[8], t[8], u[8];
    for (int i = 0; i < 8; ++i) r[i] = load(in + i * stride);
    for (int i = 0; i < 8; i += 2) {
      t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
      t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
    }
    for (int g = 0; g < 2; ++g) {
      u[4 * g + 0] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], _MM_SHUFFLE(1, 0, 1, 0));
      u[4 * g + 1] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], _MM_SHUFFLE(3, 2, 3, 2));
      u[4 * g + 2] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], _MM_SHUFFLE(1, 0, 1, 0));
      u[4 * g + 3] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], _MM_SHUFFLE(3, 2, 3, 2));
    }
    for (int q = 0; q < 4; ++q) {
      store(out + q * 8, _mm256_permute2f128_ps(u[q], u[4 + q], 0x20));
      store(out + (4 + q) * 8, _mm256_permute2f128_ps(u[q], u[4 + q], 0x31));
    }
  }
  static F add(F a, F b) { return _mm256_add_ps(a, b); }
  static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
  static F div(F a, F b) { return _mm256_div_ps(a, b); }
  static F fma(F a, F b, F c) { return _mm256_fmadd_ps(a, b, c); }
  static F fnma(F a, F b, F c) { return _mm256_fnmadd_ps(a, b, c); }
  static F min(F a, F b) { return _mm256_min_ps(a, b); }
  static F max(F a, F b) { return _mm256_max_ps(a, b); }
  static F sqrt(F a) { return _mm256_sqrt_ps(a); }
  static M lt(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
  static M ge(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
  static F select(M m, F a, F b) { return _mm256_blendv_ps(b, a, m); }
  static I trunc(F x) { return _mm256_cvttps_epi32(x); }  // NaN -> INT_MIN, clamped below
  static F to_float(I i) { return _mm256_cvtepi32_ps(i); }
  static I iclamp(I i, int lo, int hi) { return _mm256_min_epi32(_mm256_max_epi32(i, _mm256_set1_epi32(lo)), _mm256_set1_epi32(hi)); }
  static F gather(const float* base, I i) { return _mm256_i32gather_ps(base, i, 4); }
  static I iload(const int* p) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)); }
  static void sum_squares_double(const float* x, int from, int to, double* out) {
    __m256d lo = _mm256_setzero_pd(), hi = _mm256_setzero_pd();
    for (int i = from; i < to; ++i) {
      const F v = load(x + i * 8);
      const __m256d a = _mm256_cvtps_pd(_mm256_castps256_ps128(v)), b = _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1));
      lo = _mm256_fmadd_pd(a, a, lo);
      hi = _mm256_fmadd_pd(b, b, hi);
    }
    _mm256_storeu_pd(out, lo);
    _mm256_storeu_pd(out + 4, hi);
  }
  static I imul(I a, int k) { return _mm256_mullo_epi32(a, _mm256_set1_epi32(k)); }
  // rsqrt (12 bits) and one Newton step y (1.5 - 0.5 x y^2): ~23 bits. rsqrt(0) = inf stays inf.
  static F rsqrt(F x) {
    const F y = _mm256_rsqrt_ps(x);
    const F hx = _mm256_mul_ps(_mm256_set1_ps(0.5f), x);
    return _mm256_mul_ps(y, _mm256_fnmadd_ps(_mm256_mul_ps(hx, y), y, _mm256_set1_ps(1.5f)));
  }
  static bool all(M m) { return _mm256_movemask_ps(m) == 0xFF; }
  static bool any(M m) { return _mm256_movemask_ps(m) != 0; }
  static M land(M a, M b) { return _mm256_and_ps(a, b); }
  static int count(M m) { return __builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(m))); }
  template <int N>
  static void fetch_bands(const ZhTable& t, I row, F fr, F* out) {
    const I idx = _mm256_mullo_epi32(row, _mm256_set1_epi32(2 * N));
    const float* base = t.data.data();
    for (int l = 0; l < N; ++l)
      out[l] = fma(fr, _mm256_i32gather_ps(base + 2 * l + 1, idx, 4), _mm256_i32gather_ps(base + 2 * l, idx, 4));
  }
};
#include "kernel_body.hpp"
#include "batch_body.hpp"
#include "proxy_light_body.hpp"
#include "fan_body.hpp"
}  // namespace kavx2
#pragma GCC pop_options

// ---------------------------------------------------------------------------------------------
// AVX-512F, 16 lanes.
#pragma GCC push_options
#pragma GCC target("avx512f,avx2,fma")
namespace kavx512 {
struct Vec {
  using F = __m512;
  using I = __m512i;
  using M = __mmask16;
  static constexpr int W = 16;
  static F set(float x) { return _mm512_set1_ps(x); }
  static F load(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, F x) { _mm512_storeu_ps(p, x); }
  // out[k W + l] = in[l stride + k], 16 x 16: as the AVX2 version up to u (u[4g + q] holds rows
  // 4g..4g+3 of column 4L + q in 128-bit lane L), then a 4 x 4 transpose of 128-bit lanes per q.
  // The zero-masked forms of the shuffles (all lanes kept, the same instructions): GCC 12 reports the
  // plain forms' undefined source vector as used uninitialised at -O1.
  static void transpose(const float* in, std::size_t stride, float* out) {
    constexpr __mmask16 all = 0xFFFF;
    F r[16], t[16], u[16];
    for (int i = 0; i < 16; ++i) r[i] = load(in + i * stride);
    for (int i = 0; i < 16; i += 2) {
      t[i] = _mm512_maskz_unpacklo_ps(all, r[i], r[i + 1]);
      t[i + 1] = _mm512_maskz_unpackhi_ps(all, r[i], r[i + 1]);
    }
    for (int g = 0; g < 4; ++g) {
      u[4 * g + 0] = _mm512_maskz_shuffle_ps(all, t[4 * g], t[4 * g + 2], _MM_SHUFFLE(1, 0, 1, 0));
      u[4 * g + 1] = _mm512_maskz_shuffle_ps(all, t[4 * g], t[4 * g + 2], _MM_SHUFFLE(3, 2, 3, 2));
      u[4 * g + 2] = _mm512_maskz_shuffle_ps(all, t[4 * g + 1], t[4 * g + 3], _MM_SHUFFLE(1, 0, 1, 0));
      u[4 * g + 3] = _mm512_maskz_shuffle_ps(all, t[4 * g + 1], t[4 * g + 3], _MM_SHUFFLE(3, 2, 3, 2));
    }
    for (int q = 0; q < 4; ++q) {
      const F va = _mm512_maskz_shuffle_f32x4(all, u[q], u[4 + q], 0x88), vb = _mm512_maskz_shuffle_f32x4(all, u[q], u[4 + q], 0xdd);
      const F vc = _mm512_maskz_shuffle_f32x4(all, u[8 + q], u[12 + q], 0x88), vd = _mm512_maskz_shuffle_f32x4(all, u[8 + q], u[12 + q], 0xdd);
      store(out + q * 16, _mm512_maskz_shuffle_f32x4(all, va, vc, 0x88));
      store(out + (4 + q) * 16, _mm512_maskz_shuffle_f32x4(all, vb, vd, 0x88));
      store(out + (8 + q) * 16, _mm512_maskz_shuffle_f32x4(all, va, vc, 0xdd));
      store(out + (12 + q) * 16, _mm512_maskz_shuffle_f32x4(all, vb, vd, 0xdd));
    }
  }
  static F add(F a, F b) { return _mm512_add_ps(a, b); }
  static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
  static F div(F a, F b) { return _mm512_div_ps(a, b); }
  static F fma(F a, F b, F c) { return _mm512_fmadd_ps(a, b, c); }
  static F fnma(F a, F b, F c) { return _mm512_fnmadd_ps(a, b, c); }
  static F min(F a, F b) { return _mm512_min_ps(a, b); }
  static F max(F a, F b) { return _mm512_max_ps(a, b); }
  static F sqrt(F a) { return _mm512_sqrt_ps(a); }
  static M lt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  static M ge(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
  static F select(M m, F a, F b) { return _mm512_mask_blend_ps(m, b, a); }
  static I trunc(F x) { return _mm512_cvttps_epi32(x); }  // NaN -> INT_MIN, clamped below
  static F to_float(I i) { return _mm512_cvtepi32_ps(i); }
  static I iclamp(I i, int lo, int hi) { return _mm512_min_epi32(_mm512_max_epi32(i, _mm512_set1_epi32(lo)), _mm512_set1_epi32(hi)); }
  static F gather(const float* base, I i) { return _mm512_mask_i32gather_ps(_mm512_setzero_ps(), 0xFFFF, i, base, 4); }
  static I iload(const int* p) { return _mm512_loadu_si512(p); }
  static void sum_squares_double(const float* x, int from, int to, double* out) {
    __m512d lo = _mm512_setzero_pd(), hi = _mm512_setzero_pd();
    for (int i = from; i < to; ++i) {
      const F v = load(x + i * 16);
      const __m512d a = _mm512_cvtps_pd(_mm512_castps512_ps256(v));
      const __m512d b = _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1)));
      lo = _mm512_fmadd_pd(a, a, lo);
      hi = _mm512_fmadd_pd(b, b, hi);
    }
    _mm512_storeu_pd(out, lo);
    _mm512_storeu_pd(out + 8, hi);
  }
  static I imul(I a, int k) { return _mm512_mullo_epi32(a, _mm512_set1_epi32(k)); }
  // rsqrt14 (14 bits) and one Newton step: ~28 bits, below float rounding.
  static F rsqrt(F x) {
    const F y = _mm512_rsqrt14_ps(x);
    const F hx = _mm512_mul_ps(_mm512_set1_ps(0.5f), x);
    return _mm512_mul_ps(y, _mm512_fnmadd_ps(_mm512_mul_ps(hx, y), y, _mm512_set1_ps(1.5f)));
  }
  static bool all(M m) { return m == 0xFFFF; }
  static bool any(M m) { return m != 0; }
  static M land(M a, M b) { return static_cast<M>(a & b); }
  static int count(M m) { return __builtin_popcount(static_cast<unsigned>(m)); }
  // Neighbouring receivers see a blocker at nearly the same angle, so the 16 lanes' table rows
  // usually fall in a window of 16 rows around lane 0's: then each band is two loads and two
  // in-register permutes. Otherwise (value, slope) pairs come from one 64-bit gather per 8 lanes,
  // split by two permutes.
  template <int N>
  static void fetch_bands(const ZhTable& t, I row, F fr, F* out) {
    const int rows = t.rows;
    if (rows >= 16) {
      const int k0 = _mm_cvtsi128_si32(_mm512_castsi512_si128(row));
      const int start = k0 - 7 < 0 ? 0 : (k0 - 7 > rows - 16 ? rows - 16 : k0 - 7);
      const I rel = _mm512_sub_epi32(row, _mm512_set1_epi32(start));
      if (_mm512_cmplt_epu32_mask(rel, _mm512_set1_epi32(16)) == 0xFFFF) {
        for (int l = 0; l < N; ++l) {
          const float* b = t.band.data() + static_cast<std::size_t>(l) * 2 * rows + start;
          out[l] = fma(fr, _mm512_permutexvar_ps(rel, _mm512_loadu_ps(b + rows)), _mm512_permutexvar_ps(rel, _mm512_loadu_ps(b)));
        }
        return;
      }
    }
    const I idx = _mm512_mullo_epi32(row, _mm512_set1_epi32(N));
    const __m256i lo_idx = _mm512_castsi512_si256(idx), hi_idx = _mm512_extracti64x4_epi64(idx, 1);
    const I even = _mm512_set_epi32(30, 28, 26, 24, 22, 20, 18, 16, 14, 12, 10, 8, 6, 4, 2, 0);
    const I odd = _mm512_set_epi32(31, 29, 27, 25, 23, 21, 19, 17, 15, 13, 11, 9, 7, 5, 3, 1);
    for (int l = 0; l < N; ++l) {
      const float* base = t.data.data() + 2 * l;
      const F lo = _mm512_castpd_ps(_mm512_i32gather_pd(lo_idx, base, 8));
      const F hi = _mm512_castpd_ps(_mm512_i32gather_pd(hi_idx, base, 8));
      out[l] = fma(fr, _mm512_permutex2var_ps(lo, odd, hi), _mm512_permutex2var_ps(lo, even, hi));
    }
  }
};
#include "kernel_body.hpp"
#include "batch_body.hpp"
#include "proxy_light_body.hpp"
#include "fan_body.hpp"
}  // namespace kavx512
#pragma GCC pop_options

// ---------------------------------------------------------------------------------------------

const char* to_string(KernelIsa isa) {
  switch (isa) {
    case KernelIsa::Scalar: return "scalar";
    case KernelIsa::Avx2: return "avx2";
    case KernelIsa::Avx512: return "avx512";
  }
  return "?";
}

bool kernel_isa_supported(KernelIsa isa) {
  switch (isa) {
    case KernelIsa::Scalar: return true;
    case KernelIsa::Avx2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case KernelIsa::Avx512: return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }
  return false;
}

KernelIsa best_kernel_isa() {
  static const KernelIsa best = kernel_isa_supported(KernelIsa::Avx512) ? KernelIsa::Avx512
                                : kernel_isa_supported(KernelIsa::Avx2)  ? KernelIsa::Avx2
                                                                         : KernelIsa::Scalar;
  return best;
}

int kernel_lanes(KernelIsa isa) { return isa == KernelIsa::Avx512 ? 16 : isa == KernelIsa::Avx2 ? 8 : 1; }

void accumulate_log(KernelIsa isa, const ZhTable& table, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                    std::size_t end, const BlockerList& blockers, float* out) {
  const int order = table.order;
  if (order < 3 || order > kMaxAccOrder)
    throw std::invalid_argument("accumulate_log: table order " + std::to_string(order) + " outside [3, 8]");
  if (blockers.order != order)
    throw std::invalid_argument("accumulate_log: blocker weights of order " + std::to_string(blockers.order) +
                                " used with a table of order " + std::to_string(order));
  if (table.rows < 2) throw std::invalid_argument("accumulate_log: table has fewer than 2 rows");
  if (end > rec.size() || begin > end) throw std::invalid_argument("accumulate_log: receiver range outside the receivers");
  if (!kernel_isa_supported(isa))
    throw std::invalid_argument(std::string("accumulate_log: this CPU cannot run the ") + to_string(isa) + " kernel");
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::kernel_dispatch(order, table, rule, rec, begin, end, blockers, out); return;
    case KernelIsa::Avx2: kavx2::kernel_dispatch(order, table, rule, rec, begin, end, blockers, out); return;
    case KernelIsa::Avx512: kavx512::kernel_dispatch(order, table, rule, rec, begin, end, blockers, out); return;
  }
}

long long accumulate_product_batch(KernelIsa isa, const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec,
                                   std::size_t begin, std::size_t end, const BlockerList& blockers, float* out) {
  const int order = vis_table.order;
  if (order < 3 || order > kMaxAccOrder)
    throw std::invalid_argument("accumulate_product_batch: table order " + std::to_string(order) + " outside [3, 8]");
  if (vis_table.rows < 2) throw std::invalid_argument("accumulate_product_batch: table has fewer than 2 rows");
  if (end > rec.size() || begin > end) throw std::invalid_argument("accumulate_product_batch: receiver range outside the receivers");
  if (!kernel_isa_supported(isa))
    throw std::invalid_argument(std::string("accumulate_product_batch: this CPU cannot run ") + to_string(isa));
  const ProductPlan& plan = ProductPlan::get(order);
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: return kscalar::product_dispatch(order, vis_table, rule, rec, begin, end, blockers, plan, out);
    case KernelIsa::Avx2: return kavx2::product_dispatch(order, vis_table, rule, rec, begin, end, blockers, plan, out);
    case KernelIsa::Avx512: return kavx512::product_dispatch(order, vis_table, rule, rec, begin, end, blockers, plan, out);
  }
  return 0;
}

long long accumulate_proxy_lights(KernelIsa isa, const ProxyLightTables& t, const ReceiverSoA& rec, std::size_t begin,
                                  std::size_t end, const ProxyLightList& lights, float* rgb, float* omega) {
  if (!t.vis || !t.ltilde || !t.vh) throw std::invalid_argument("accumulate_proxy_lights: incomplete tables");
  const int order = t.vis->order;
  if (order < kMinOrder || order > kMaxOrder)
    throw std::invalid_argument("accumulate_proxy_lights: table order " + std::to_string(order) + " outside [" +
                                std::to_string(kMinOrder) + ", " + std::to_string(kMaxOrder) + "]");
  if (t.vis->rows < 2) throw std::invalid_argument("accumulate_proxy_lights: table has fewer than 2 rows");
  if (t.band_factor && (t.band_factor->order != order || t.band_factor->rows != t.vis->rows || t.band_factor->scale != t.vis->scale))
    throw std::invalid_argument("accumulate_proxy_lights: the band-factor table's rows differ from the visibility table's");
  if (t.eta > 0.0f && !(t.eta > 1.0f))
    throw std::invalid_argument("accumulate_proxy_lights: a sphere of influence needs eta > 1, got " + std::to_string(t.eta));
  if (!std::isfinite(t.eta) || !std::isfinite(t.reach)) throw std::invalid_argument("accumulate_proxy_lights: eta or reach not finite");
  if (end > rec.size() || begin > end) throw std::invalid_argument("accumulate_proxy_lights: receiver range outside the receivers");
  if (begin == end || lights.count == 0) return 0;
  if (!rgb || !omega) throw std::invalid_argument("accumulate_proxy_lights: null output buffer");
  if (!kernel_isa_supported(isa))
    throw std::invalid_argument(std::string("accumulate_proxy_lights: this CPU cannot run the ") + to_string(isa) + " kernel");
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: return kscalar::proxy_light_dispatch(order, t, rec, begin, end, lights, rgb, omega);
    case KernelIsa::Avx2: return kavx2::proxy_light_dispatch(order, t, rec, begin, end, lights, rgb, omega);
    case KernelIsa::Avx512: return kavx512::proxy_light_dispatch(order, t, rec, begin, end, lights, rgb, omega);
  }
  return 0;
}

void sphere_fan(KernelIsa isa, const ZhTable& log, ReplacementRule rule, const glm::vec3& p, const glm::vec3& n, const SphereFan& s,
                float* g, float* key, std::uint8_t* alive, float* rgb) {
  const int order = log.order;
  if (order < 3 || order > kMaxAccOrder)
    throw std::invalid_argument("sphere_fan: table order " + std::to_string(order) + " outside [3, 8]");
  if (log.rows < 2) throw std::invalid_argument("sphere_fan: table has fewer than 2 rows");
  if (s.count == 0) return;
  if (!s.cx || !s.cy || !s.cz || !s.r || !g || !key || !alive) throw std::invalid_argument("sphere_fan: null sphere or output array");
  if (s.L && (!s.id || !s.rot || !s.weight || s.weight_rows < 2 || !rgb))
    throw std::invalid_argument("sphere_fan: emission without indices, rotations, a weight table of 2 rows or more, or an output");
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string("sphere_fan: this CPU cannot run ") + to_string(isa));
  const float pn[6] = {p.x, p.y, p.z, n.x, n.y, n.z};
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::fan_dispatch(order, log, rule, pn, s, g, key, alive, rgb); return;
    case KernelIsa::Avx2: kavx2::fan_dispatch(order, log, rule, pn, s, g, key, alive, rgb); return;
    case KernelIsa::Avx512: kavx512::fan_dispatch(order, log, rule, pn, s, g, key, alive, rgb); return;
  }
}

bool exp_batch_supports(sh::ExpMethod m) {
  return m == sh::ExpMethod::HYB || m == sh::ExpMethod::OL || m == sh::ExpMethod::PSStar || m == sh::ExpMethod::PS;
}

void exp_batch(KernelIsa isa, const BatchExp& e, const float* f, float* g, std::size_t count, std::size_t first,
               sh::ExpStats& stats) {
  if (!exp_batch_supports(e.method)) throw std::invalid_argument(std::string("exp_batch: method ") + sh::to_string(e.method) + " is not batched");
  if (!e.plan || e.plan->order != e.order) throw std::invalid_argument("exp_batch: product plan missing or of another order");
  if ((e.method == sh::ExpMethod::HYB || e.method == sh::ExpMethod::OL) && (!e.tables || e.tables->order() != e.order))
    throw std::invalid_argument("exp_batch: OL tables missing or of another order");
  if ((e.method == sh::ExpMethod::PSStar || e.method == sh::ExpMethod::PS) && (e.degree < 1 || e.degree > 200))
    throw std::invalid_argument("exp_batch: series degree " + std::to_string(e.degree) + " outside [1, 200]");
  if (count == 0) return;
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string("exp_batch: this CPU cannot run ") + to_string(isa));
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::exp_dispatch(e, f, count, g, first, stats); return;
    case KernelIsa::Avx2: kavx2::exp_dispatch(e, f, count, g, first, stats); return;
    case KernelIsa::Avx512: kavx512::exp_dispatch(e, f, count, g, first, stats); return;
  }
}

namespace {

void products(const char* what, KernelIsa isa, int order, const float* f, const float* g, float* out, std::size_t count) {
  if (order < 1 || order > kMaxAccOrder) throw std::invalid_argument(std::string(what) + ": order " + std::to_string(order) + " outside [1, 8]");
  if (count == 0) return;
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string(what) + ": this CPU cannot run " + to_string(isa));
  const ProductPlan& p = ProductPlan::get(order);
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::product_dispatch(p, f, g, out, count); return;
    case KernelIsa::Avx2: kavx2::product_dispatch(p, f, g, out, count); return;
    case KernelIsa::Avx512: kavx512::product_dispatch(p, f, g, out, count); return;
  }
}

}  // namespace

void square_batch(KernelIsa isa, int order, const float* f, float* out, std::size_t count) {
  products("square_batch", isa, order, f, nullptr, out, count);
}

void product_batch(KernelIsa isa, int order, const float* f, const float* g, float* out, std::size_t count) {
  products("product_batch", isa, order, f, g, out, count);
}

BatchShade BatchShade::make(int order, const float* L, const float* hcoef, const float* gwin, const float* g) {
  BatchShade b;
  b.order = order;
  b.plan = &ProductPlan::get(order);
  b.L = L;
  b.hcoef = hcoef;
  b.gwin = gwin;
  b.g = g;
  return b;
}

void shade_batch(KernelIsa isa, const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out) {
  if (!b.plan || b.plan->order != b.order || !b.L || !b.hcoef || !b.gwin)
    throw std::invalid_argument("shade_batch: incomplete shading inputs");
  if (b.taps && (!b.taps->pixel || !b.taps->index || !b.taps->weight || !b.taps->coarse))
    throw std::invalid_argument("shade_batch: incomplete interpolation taps");
  if (b.transfer && (!b.taps || (b.taps->out && !b.transfer->carries_visibility)))
    throw std::invalid_argument("shade_batch: transfer rows need interpolation taps, and rows that carry the visibility to write it out");
  if (b.transfer && (b.transfer->order != b.order || b.transfer->at.size() != static_cast<std::size_t>(3 * b.order * b.order * b.order * b.order) ||
                     b.transfer->unshadowed.size() != static_cast<std::size_t>(b.transfer->stride())))
    throw std::invalid_argument("shade_batch: transfer rows of order " + std::to_string(b.transfer->order) + " for order " +
                                std::to_string(b.order));
  if (end > rec.size() || begin > end) throw std::invalid_argument("shade_batch: receiver range outside the receivers");
  if (begin == end) return;
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string("shade_batch: this CPU cannot run ") + to_string(isa));
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::shade_dispatch(b, rec, begin, end, out); return;
    case KernelIsa::Avx2: kavx2::shade_dispatch(b, rec, begin, end, out); return;
    case KernelIsa::Avx512: kavx512::shade_dispatch(b, rec, begin, end, out); return;
  }
}

void lights_batch(KernelIsa isa, const LightLobeTable& table, const std::vector<scene::SphericalLight>& lights, int order,
                  const float* gwin, const ReceiverSoA& rec, std::size_t begin, std::size_t end, const float* g, glm::vec3* out) {
  if (table.order != order || order < 1 || order > kMaxAccOrder)
    throw std::invalid_argument("lights_batch: light table of order " + std::to_string(table.order) + " for shading order " +
                                std::to_string(order));
  if (!gwin) throw std::invalid_argument("lights_batch: no visibility window");
  if (end > rec.size() || begin > end) throw std::invalid_argument("lights_batch: receiver range outside the receivers");
  if (begin == end || lights.empty()) return;
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string("lights_batch: this CPU cannot run ") + to_string(isa));
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::lights_dispatch(table, lights, gwin, rec, begin, end, g, out); return;
    case KernelIsa::Avx2: kavx2::lights_dispatch(table, lights, gwin, rec, begin, end, g, out); return;
    case KernelIsa::Avx512: kavx512::lights_dispatch(table, lights, gwin, rec, begin, end, g, out); return;
  }
}

ShadeTransfer ShadeTransfer::make(const BatchShade& b, bool carries_visibility) {
  if (!b.plan || b.plan->order != b.order || !b.L || !b.hcoef || !b.gwin)
    throw std::invalid_argument("ShadeTransfer: incomplete shading inputs");
  const ProductPlan& p = *b.plan;
  const int n2 = b.order * b.order, m = 3 * n2;
  // A_c[a][b] = sum_k C_abk L_c,k from the plan's terms: out_k += v (f_j g_l + f_l g_j) for j < l,
  // v f_j g_j on the diagonal, with f = H(N) (index a) and g the windowed visibility (index b).
  std::vector<double> A(static_cast<std::size_t>(3) * n2 * n2, 0.0);
  const auto add = [&](int a, int bb, double v, int k) {
    for (int c = 0; c < 3; ++c) A[(static_cast<std::size_t>(c) * n2 + a) * n2 + bb] += v * b.L[c * n2 + k];
  };
  for (int k = 0; k < n2; ++k) {
    for (int t = p.pr_begin[k]; t < p.pr_offdiag_end[k]; ++t) {
      add(p.pr_j[t], p.pr_k[t], p.pr_v[t], k);
      add(p.pr_k[t], p.pr_j[t], p.pr_v[t], k);
    }
    for (int t = p.pr_offdiag_end[k]; t < p.pr_begin[k + 1]; ++t) add(p.pr_j[t], p.pr_j[t], p.pr_v[t], k);
  }
  ShadeTransfer t;
  t.order = b.order;
  t.carries_visibility = carries_visibility;
  t.at.assign(static_cast<std::size_t>(n2) * m, 0.0f);
  t.unshadowed.assign(t.stride(), 0.0f);
  if (carries_visibility) t.unshadowed[m] = static_cast<float>(sh::kSqrt4Pi);
  for (int bb = 0; bb < n2; ++bb)
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < n2; ++a) {
        const double v = static_cast<double>(b.hcoef[a]) * A[(static_cast<std::size_t>(c) * n2 + a) * n2 + bb] * b.gwin[bb];
        t.at[static_cast<std::size_t>(bb) * m + c * n2 + a] = static_cast<float>(v);
        if (bb == 0) t.unshadowed[c * n2 + a] = static_cast<float>(sh::kSqrt4Pi * v);
      }
  return t;
}

void transfer_rows(KernelIsa isa, const ShadeTransfer& t, const float* g, std::size_t count, float* r) {
  if (t.order < 1 || t.order > kMaxAccOrder || t.at.size() != static_cast<std::size_t>(3 * t.order * t.order * t.order * t.order))
    throw std::invalid_argument("transfer_rows: malformed transfer of order " + std::to_string(t.order));
  if (count == 0) return;
  if (!kernel_isa_supported(isa)) throw std::invalid_argument(std::string("transfer_rows: this CPU cannot run ") + to_string(isa));
  FlushDenormals ftz;
  switch (isa) {
    case KernelIsa::Scalar: kscalar::transfer_rows_dispatch(t, g, count, r); return;
    case KernelIsa::Avx2: kavx2::transfer_rows_dispatch(t, g, count, r); return;
    case KernelIsa::Avx512: kavx512::transfer_rows_dispatch(t, g, count, r); return;
  }
}

double kernel_flops_per_pair(int order, ReplacementRule rule, bool straddling) {
  if (order < 3 || order > kMaxAccOrder) throw std::invalid_argument("kernel_flops_per_pair: order outside [3, 8]");
  // Any table and geometry will do: the kernel is branch-free apart from the rule, which is uniform.
  ZhTable t;
  t.order = order;
  t.rows = 4;
  t.scale = static_cast<float>(3.0 / (sh::kPi / 2));
  t.data.assign(static_cast<std::size_t>(t.rows) * 2 * order, 0.5f);
  t.band.assign(t.data.size(), 0.5f);
  BlockerList b;
  b.order = order;
  constexpr int kBlockers = 4;
  // Centre height 1 above the receiver's tangent plane: radius 0.5 is entirely in front (the rules'
  // fast path), radius 1.5 straddles the plane (the rules run).
  for (int i = 0; i < kBlockers; ++i) b.push(glm::vec3(0.3f * i, 1.0f, 0.2f), straddling ? 1.5f : 0.5f, nullptr);
  ReceiverSoA rec;
  rec.resize(1);
  rec.set(0, glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f));
  std::vector<float> out(static_cast<std::size_t>(order) * order);
  kcount::g_flops = 0.0;
  kcount::kernel_dispatch(order, t, rule, rec, 0, 1, b, out.data());
  return kcount::g_flops / kBlockers;
}

}  // namespace softgi::techniques::common
