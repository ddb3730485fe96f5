// This machine's single-precision FMA peak, measured: an FMA-bound loop (the widest vector FMA the
// CPU runs, AVX-512 or AVX2) on each of `threads` threads. Shared by the benchmarks that report a
// kernel's share of peak (bench_shexp, bench_image_splat, bench_spherical_lights).
#pragma once

#include <immintrin.h>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "measured_limit.hpp"

namespace softgi::bench {

inline constexpr int kFmaChains = 12;  // independent accumulators: > latency (4) x FMA ports (2)

// GCC 12 reports its own AVX-512 intrinsics as maybe uninitialised (see techniques/common/kernel.cpp).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
__attribute__((target("avx512f"))) inline float fma_loop_avx512(long iters) {
  __m512 a[kFmaChains];
  const __m512 m = _mm512_set1_ps(0.9999999f), c = _mm512_set1_ps(1e-7f);
  for (int i = 0; i < kFmaChains; ++i) a[i] = _mm512_set1_ps(static_cast<float>(i));
  for (long k = 0; k < iters; ++k)
#pragma GCC unroll 12
    for (int i = 0; i < kFmaChains; ++i) a[i] = _mm512_fmadd_ps(a[i], m, c);
  __m512 s = a[0];
  for (int i = 1; i < kFmaChains; ++i) s = _mm512_add_ps(s, a[i]);
  return _mm512_reduce_add_ps(s);
}

__attribute__((target("avx2,fma"))) inline float fma_loop_avx2(long iters) {
  __m256 a[kFmaChains];
  const __m256 m = _mm256_set1_ps(0.9999999f), c = _mm256_set1_ps(1e-7f);
  for (int i = 0; i < kFmaChains; ++i) a[i] = _mm256_set1_ps(static_cast<float>(i));
  for (long k = 0; k < iters; ++k)
#pragma GCC unroll 12
    for (int i = 0; i < kFmaChains; ++i) a[i] = _mm256_fmadd_ps(a[i], m, c);
  alignas(32) float out[8];
  __m256 s = a[0];
  for (int i = 1; i < kFmaChains; ++i) s = _mm256_add_ps(s, a[i]);
  _mm256_store_ps(out, s);
  return out[0];
}
#pragma GCC diagnostic pop

// GFLOP/s of `threads` threads each running the widest FMA loop this CPU has for `iters` rounds.
inline double fma_gflops(int threads, long iters) {
  const bool avx512 = __builtin_cpu_supports("avx512f");
  const int lanes = avx512 ? 16 : 8;
  std::vector<std::thread> pool;
  std::vector<float> sink(threads);
  auto t0 = std::chrono::steady_clock::now();
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] { sink[t] = avx512 ? fma_loop_avx512(iters) : fma_loop_avx2(iters); });
  for (auto& th : pool) th.join();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  benchmark::DoNotOptimize(sink);
  return static_cast<double>(threads) * iters * kFmaChains * lanes * 2.0 / s * 1e-9;
}

// The best of five 2-thread runs, measured once per process (raised by record_peak).
inline MeasuredLimit& fma_peak_limit() {
  static MeasuredLimit peak;
  return peak;
}
inline double peak_gflops() {
  return fma_peak_limit().get([] { return fma_gflops(2, 20'000'000); });
}
// A BM_FmaPeak run with 2 threads that saw more raises the peak later shares are taken of.
inline void record_peak(double gflops_two_threads) { fma_peak_limit().raise(gflops_two_threads); }

// The benchmark body each frame-level benchmark registers as BM_FmaPeak (Args 1 and 2 threads):
// the best of its iterations, and at 2 threads the peak the shares of peak are taken against.
inline void BM_FmaPeak(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  double best = 0.0;
  for (auto _ : state) best = std::max(best, fma_gflops(threads, 20'000'000));
  state.counters["GFLOP/s"] = best;
  if (threads == 2) record_peak(best);
}

}  // namespace softgi::bench
