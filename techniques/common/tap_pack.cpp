// pack_taps (tap_pack.hpp). Packing is data movement only: both paths write the same bits. GCC does
// not vectorise the portable loop (a store to a slot that depends on the taps before it), and its
// own attempt at a vector form of it stayed in 256-bit registers with spills; the AVX-512 path
// below is written with intrinsics instead: sixteen pixels at a time, their four tap rows
// transposed into one 16-lane vector per four pixels, then per vector one compress of the kept
// lanes and one expand into the first slots of each pixel (both keep lane order, so each pixel's
// taps land in its own slots, in tap order).
#include "tap_pack.hpp"

// GCC 12 reports its own AVX-512 intrinsics (the _mm512_undefined_* self-initialisation inside
// unpack and shuffle) as maybe uninitialised once inlined; the warning is about the compiler's
// header, not this code.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>

namespace softgi::techniques::common::detail {

static_assert(sizeof(std::array<std::int32_t, 4>) == 16 && sizeof(std::array<float, 4>) == 16);

void pack_taps_portable(const std::int32_t* tap, const float* weight, const float* live, int stride, int n,
                        std::array<std::int32_t, 4>* out_index, std::array<float, 4>* out_weight) {
  for (int t = 0; t < n; ++t) {
    std::array<std::int32_t, 4> oi{-1, -1, -1, -1};
    std::array<float, 4> ow{0.0f, 0.0f, 0.0f, 0.0f};
    int m = 0;
    for (int k = 0; k < 4; ++k) {
      const std::size_t i = static_cast<std::size_t>(k) * stride + t;
      if (live[i] > 0.0f) {
        oi[m] = tap[i];
        ow[m] = weight[i];
        ++m;
      }
    }
    out_index[t] = oi;
    out_weight[t] = ow;
  }
}

namespace {

// Rows r0..r3 (tap k of pixels 0..15) to four vectors of four pixels each, pixel p's taps in lanes
// 4 (p mod 4) .. 4 (p mod 4) + 3 of vector p / 4: a 4x4 transpose within each 128-bit block (which
// leaves block b of vector j holding pixel 4 b + j), then one of the 128-bit blocks.
__attribute__((target("avx512f"))) inline void transpose(const __m512i r[4], __m512i out[4]) {
  const __m512i a = _mm512_unpacklo_epi32(r[0], r[1]), b = _mm512_unpackhi_epi32(r[0], r[1]);
  const __m512i c = _mm512_unpacklo_epi32(r[2], r[3]), d = _mm512_unpackhi_epi32(r[2], r[3]);
  const __m512i z0 = _mm512_unpacklo_epi64(a, c), z1 = _mm512_unpackhi_epi64(a, c);  // pixels 0,4,8,12 and 1,5,9,13
  const __m512i z2 = _mm512_unpacklo_epi64(b, d), z3 = _mm512_unpackhi_epi64(b, d);  // pixels 2,6,10,14 and 3,7,11,15
  const __m512i t0 = _mm512_shuffle_i32x4(z0, z1, _MM_SHUFFLE(1, 0, 1, 0));           // 0, 4, 1, 5
  const __m512i t1 = _mm512_shuffle_i32x4(z0, z1, _MM_SHUFFLE(3, 2, 3, 2));           // 8, 12, 9, 13
  const __m512i t2 = _mm512_shuffle_i32x4(z2, z3, _MM_SHUFFLE(1, 0, 1, 0));           // 2, 6, 3, 7
  const __m512i t3 = _mm512_shuffle_i32x4(z2, z3, _MM_SHUFFLE(3, 2, 3, 2));           // 10, 14, 11, 15
  out[0] = _mm512_shuffle_i32x4(t0, t2, _MM_SHUFFLE(2, 0, 2, 0));                     // 0, 1, 2, 3
  out[1] = _mm512_shuffle_i32x4(t0, t2, _MM_SHUFFLE(3, 1, 3, 1));                     // 4, 5, 6, 7
  out[2] = _mm512_shuffle_i32x4(t1, t3, _MM_SHUFFLE(2, 0, 2, 0));                     // 8, 9, 10, 11
  out[3] = _mm512_shuffle_i32x4(t1, t3, _MM_SHUFFLE(3, 1, 3, 1));                     // 12, 13, 14, 15
}

__attribute__((target("avx512f,bmi2"))) void pack_avx512(const std::int32_t* tap, const float* weight, const float* live,
                                                          int stride, int n, std::array<std::int32_t, 4>* out_index,
                                                          std::array<float, 4>* out_weight) {
  // The first popcount(m) of a pixel's four lanes, for each 4-bit mask m of kept taps.
  static constexpr unsigned kSlots[16] = {0, 1, 1, 3, 1, 3, 3, 7, 1, 3, 3, 7, 3, 7, 7, 15};
  // Bit k of every nibble: tap k's bit of each pixel, once the rows' masks are spread (pdep).
  static constexpr unsigned long long kTapBit[4] = {0x1111111111111111ull, 0x2222222222222222ull, 0x4444444444444444ull,
                                                    0x8888888888888888ull};
  const __m512i none = _mm512_set1_epi32(-1);
  const __m512 zero = _mm512_setzero_ps();
  int t = 0;
  for (; t + 16 <= n; t += 16) {
    __m512i idx[4], wgt[4];
    unsigned long long kept = 0;  // bit 4 p + k: pixel t + p keeps tap k
    for (int k = 0; k < 4; ++k) {
      const std::size_t i = static_cast<std::size_t>(k) * stride + t;
      idx[k] = _mm512_loadu_si512(tap + i);
      wgt[k] = _mm512_castps_si512(_mm512_loadu_ps(weight + i));
      const __mmask16 m = _mm512_cmp_ps_mask(_mm512_loadu_ps(live + i), zero, _CMP_GT_OQ);
      kept |= _pdep_u64(static_cast<unsigned long long>(m), kTapBit[k]);
    }
    __m512i pidx[4], pwgt[4];
    transpose(idx, pidx);
    transpose(wgt, pwgt);
    for (int j = 0; j < 4; ++j) {
      const unsigned m = static_cast<unsigned>(kept >> (16 * j)) & 0xffffu;
      const __mmask16 keep = static_cast<__mmask16>(m);
      const __mmask16 slots = static_cast<__mmask16>(kSlots[m & 15u] | kSlots[(m >> 4) & 15u] << 4 | kSlots[(m >> 8) & 15u] << 8 |
                                                     kSlots[m >> 12] << 12);
      const __m512i oi = _mm512_mask_expand_epi32(none, slots, _mm512_maskz_compress_epi32(keep, pidx[j]));
      const __m512 ow = _mm512_mask_expand_ps(zero, slots, _mm512_maskz_compress_ps(keep, _mm512_castsi512_ps(pwgt[j])));
      _mm512_storeu_si512(out_index + t + 4 * j, oi);
      _mm512_storeu_ps(out_weight[t + 4 * j].data(), ow);
    }
  }
  if (t < n)
    pack_taps_portable(tap + t, weight + t, live + t, stride, n - t, out_index + t, out_weight + t);
}

bool has_avx512() { return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("bmi2"); }

}  // namespace

bool pack_taps_vectorised() {
  static const bool yes = has_avx512();
  return yes;
}

void pack_taps(const std::int32_t* tap, const float* weight, const float* live, int stride, int n,
               std::array<std::int32_t, 4>* out_index, std::array<float, 4>* out_weight) {
  if (n <= 0) return;
  if (pack_taps_vectorised())
    pack_avx512(tap, weight, live, stride, n, out_index, out_weight);
  else
    pack_taps_portable(tap, weight, live, stride, n, out_index, out_weight);
}

}  // namespace softgi::techniques::common::detail
