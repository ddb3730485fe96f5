// This machine's memory bandwidth, measured: a STREAM triad (a[i] = b[i] + s c[i]) over float
// arrays far larger than the last-level cache, split across `threads` threads. Bytes are counted as
// STREAM counts them, 12 per element (two reads and one write; the write-allocate read of `a` is not
// counted, so the figure is the bandwidth a streaming kernel can use). Shared by the frame
// benchmarks that report a display-resolution pass's share of the bandwidth.
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <thread>
#include <string>
#include <vector>

#include "measured_limit.hpp"
#include "softgi/render/technique.hpp"

namespace softgi::bench {

// 3 arrays x 32 Mi floats = 384 MiB: beyond any L3 this runs on.
inline constexpr std::size_t kTriadElements = std::size_t(32) << 20;

struct TriadArrays {
  std::vector<float> a, b, c;
  TriadArrays() : a(kTriadElements, 0.0f), b(kTriadElements, 1.0f), c(kTriadElements, 2.0f) {}  // pages touched once here
};
inline TriadArrays& triad_arrays() {
  static TriadArrays t;
  return t;
}

// GB/s of one triad pass over the arrays on `threads` threads (each a contiguous share).
inline double triad_gbps(int threads) {
  TriadArrays& t = triad_arrays();
  const std::size_t n = kTriadElements, per = (n + threads - 1) / threads;
  const float s = 3.0f;
  std::vector<std::thread> pool;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < threads; ++k)
    pool.emplace_back([&, k] {
      const std::size_t lo = k * per, hi = std::min(n, lo + per);
      float* __restrict a = t.a.data();
      const float* __restrict b = t.b.data();
      const float* __restrict c = t.c.data();
      for (std::size_t i = lo; i < hi; ++i) a[i] = b[i] + s * c[i];
    });
  for (auto& th : pool) th.join();
  const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  benchmark::DoNotOptimize(t.a.data());
  return static_cast<double>(n) * 12.0 / sec * 1e-9;
}

inline MeasuredLimit& bandwidth_limit() {
  static MeasuredLimit bw;
  return bw;
}
// The best of five 2-thread triads, measured once per process (raised by BM_StreamTriad/2).
inline double bandwidth_gbps() {
  return bandwidth_limit().get([] { return triad_gbps(2); });
}

// BM_StreamTriad/<threads>: the best of its iterations; at 2 threads, the bandwidth that shares are
// taken against.
inline void BM_StreamTriad(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  triad_gbps(threads);  // first touch outside the timing
  double best = 0.0;
  for (auto _ : state) best = std::max(best, triad_gbps(threads));
  state.counters["GB/s"] = best;
  if (threads == 2) bandwidth_limit().raise(best);
}

// Bytes a display-resolution pass must move at the least for a width x height frame, for passes
// that do not record their own "bytes_moved" counter (compose does): every plane it reads once and
// every plane it writes once, at the sizes the CPU backend stores them
// (render::gbuffer_bytes, render::image_bytes); -1 for a pass without a model. A lower bound: the
// gathers to_image makes (three vertices per pixel) add more where they miss the cache.
//   gbuffer:  writes every G-buffer plane (the CPU pass records its own count: the planes the
//             frame's G-buffer holds);
//   to_image: reads object, primitive (4 bytes each) and barycentric (8), writes one image (the
//             albedo it multiplies by is derived from the scene, not read);
//   compose:  reads direct and indirect, writes final (its own counter knows when there is no indirect).
inline double display_pass_bytes(const std::string& pass, int width, int height) {
  const double px = static_cast<double>(render::pixel_count(width, height));
  const double image = static_cast<double>(render::image_bytes(width, height));
  if (pass == "gbuffer") return static_cast<double>(render::gbuffer_bytes(width, height));
  if (pass == "to_image") return px * 16.0 + image;
  if (pass == "compose") return 3.0 * image;
  return -1.0;
}

}  // namespace softgi::bench
