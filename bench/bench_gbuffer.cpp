// The CPU backend's shared G-buffer pass with each of its primary-visibility methods, side by side in
// one run: rasterised (the default) and Embree-traced (SOFTGI_CPU_VISIBILITY=embree), on the
// built-in scenes at 512x512 and 1024x1024, the scene animated between frames (so Embree refits and
// the rasteriser sets up every triangle each frame, as in a frame of a technique).
//
//   ./build/bench/bench_gbuffer
//
// Reported per frame: the pass's wall time (the benchmark's time), visibility_ms (which triangle
// each pixel sees: Embree's BVH update and trace, or the rasteriser's set-up, binning and tile
// tests), resolve_ms (the surface attributes from them, the same code for both), and for the
// rasteriser its set-up share.
//
// Also BM_Upsample/<scene>/<weights|apply>: image_splat's bilateral upsampling from a 256x256
// receiver buffer to 1024x1024 on its own (BM_Upsample below), with its bytes moved and its share of
// the memory bandwidth (BM_StreamTriad, run first).
//
// And BM_HostCopy/<memcpy|context>: the host copy a Vulkan upload or download of a display plane
// makes into or out of mapped memory (32 MiB, about a 1024x1024 frame's eq. 11 taps and weights),
// one std::memcpy against vulkan::copy_bytes (blocks on every core), with their share of the triad.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "../techniques/common/upsample.hpp"
#include "bandwidth.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/frame_pool.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

void BM_GBuffer(benchmark::State& state, const std::string& scene_name, const std::string& visibility, int side) {
  backends::register_cpu_backend();  // and with it the CPU shared passes
  const render::PassFn* fn = render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName);
  if (!fn) {
    state.SkipWithError("the CPU backend has no gbuffer pass");
    return;
  }
  const scene::Scene sc = scene::make_builtin(scene_name);
  setenv("SOFTGI_CPU_VISIBILITY", visibility.c_str(), 1);
  render::FramePool pool;
  const render::ParamSet params;
  double t = 0.0, vis = 0.0, resolve = 0.0, setup = 0.0, hits = 0.0;
  auto frame = [&](bool count) {
    const scene::PosedScene posed = scene::evaluate(sc, t);
    t += 1.0 / 30.0;
    render::FrameResult result;
    render::FrameContext ctx(sc, posed, params, side, side, result, nullptr, &pool);
    result.passes.push_back(render::PassRecord{"gbuffer"});
    const auto t0 = std::chrono::steady_clock::now();
    (*fn)(ctx);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto& c = result.passes.back().counters;
    if (count) {
      vis += c.at("visibility_seconds");
      resolve += c.at("resolve_seconds");
      hits += c.at("hits");
      if (const auto s = c.find("raster_setup_seconds"); s != c.end()) setup += s->second;
    }
    ctx.release_to_pool();
    return wall;
  };
  try {
    frame(false);  // warm-up: the Embree scene's first build, the rasteriser's working memory
    for (auto _ : state) state.SetIterationTime(frame(true));
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
  unsetenv("SOFTGI_CPU_VISIBILITY");
  const double n = static_cast<double>(state.iterations());
  state.counters["visibility_ms"] = vis / n * 1e3;
  state.counters["resolve_ms"] = resolve / n * 1e3;
  if (visibility == "raster") state.counters["raster_setup_ms"] = setup / n * 1e3;
  state.counters["hits"] = hits / n;
  state.counters["Msamples/s"] = benchmark::Counter(static_cast<double>(side) * side * n / 1e6 / vis);
}

// The display and receiver G-buffers of one frame of `scene_name`: the receiver buffer is the same
// camera at side / scale pixels, as image_splat's receiver_gbuffer pass renders it.
struct UpsamplePair {
  render::GBuffer fine, coarse;
};
UpsamplePair upsample_pair(const std::string& scene_name, int side, int scale) {
  backends::register_cpu_backend();
  const render::PassFn* fn = render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName);
  if (!fn) throw std::runtime_error("the CPU backend has no gbuffer pass");
  const scene::Scene sc = scene::make_builtin(scene_name);
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params;
  render::FramePool pool;
  auto render_at = [&](int s) {
    render::FrameResult result;
    render::FrameContext ctx(sc, posed, params, s, s, result, nullptr, &pool);
    result.passes.push_back(render::PassRecord{"gbuffer"});
    (*fn)(ctx);
    return std::move(ctx.get<render::GBuffer>(render::kGBuffer));
  };
  UpsamplePair p{render_at(side), render_at(side / scale)};
  p.coarse.scale = scale;
  return p;
}

// image_splat's upsample pass on its own (paper 000 section 4.2): the eq. 11 weights of every
// display pixel (weights) or their application to a 3-channel coarse field (apply, the indirect
// light), at 1024x1024 from 256x256 receivers. Bytes moved, a lower bound: weights read each display
// pixel's depth and normal (16 bytes) and write its 4 indices, 4 weights and miss flag (33); apply
// reads the indices and weights (32) and writes 3 floats (12); the coarse buffers (1/16 of the pixels)
// are not counted. The share is of the 2-thread triad, measured first in the same run.
void BM_Upsample(benchmark::State& state, const std::string& scene_name, bool apply) {
  constexpr int kSide = 1024, kScale = 4;
  UpsamplePair pair;
  try {
    pair = upsample_pair(scene_name, kSide, kScale);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const techniques::common::PlaneView fine = techniques::common::plane_view(pair.fine);
  techniques::common::PlaneView coarse = techniques::common::plane_view(pair.coarse);
  coarse.scale = kScale;
  const techniques::common::UpsampleOptions opt;
  render::FramePool pool;
  techniques::common::UpsampleWeights w = techniques::common::upsample_weights(coarse, fine, opt, &pool);
  std::vector<float> in(pair.coarse.depth.size() * 3, 0.5f), out(pair.fine.depth.size() * 3, 0.0f);
  for (auto _ : state) {
    if (apply) {
      techniques::common::upsample_apply(w, in.data(), 3, out.data());
      benchmark::DoNotOptimize(out.data());
    } else {
      pool.give(std::move(w.index));
      pool.give(std::move(w.weight));
      pool.give(std::move(w.miss));
      w = techniques::common::upsample_weights(coarse, fine, opt, &pool);
      benchmark::DoNotOptimize(w.weight.data());
    }
  }
  const double px = static_cast<double>(pair.fine.depth.size());
  const double bytes = px * (apply ? 32.0 + 12.0 : 16.0 + 33.0);
  const double bw = bench::bandwidth_gbps();
  state.counters["MB_moved"] = bytes / 1e6;
  state.counters["GB/s"] = benchmark::Counter(bytes * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["surface_pixels"] = static_cast<double>(std::count_if(pair.fine.object.begin(), pair.fine.object.end(), [](std::int32_t o) { return o >= 0; }));
  state.counters["triad_GB/s"] = bw;
  state.counters["share_of_triad"] = benchmark::Counter(bytes * 1e-9 / bw, benchmark::Counter::kIsIterationInvariantRate);
}

// Copies 32 MiB between two host arrays (first touched outside the timing); bytes moved: read once,
// written once (64 MiB), against the 2-thread triad.
void BM_HostCopy(benchmark::State& state, bool blocks) {
  constexpr std::size_t kBytes = std::size_t{32} << 20;
  std::vector<char> src(kBytes, 1), dst(kBytes, 0);
  for (auto _ : state) {
    if (blocks)
      backends::vulkan::copy_bytes(dst.data(), src.data(), kBytes);
    else
      std::memcpy(dst.data(), src.data(), kBytes);
    benchmark::DoNotOptimize(dst.data());
    benchmark::ClobberMemory();
  }
  const double bytes = 2.0 * static_cast<double>(kBytes), bw = bench::bandwidth_gbps();
  state.counters["GB/s"] = benchmark::Counter(bytes * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["triad_GB/s"] = bw;
  state.counters["share_of_triad"] = benchmark::Counter(bytes * 1e-9 / bw, benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::RegisterBenchmark("BM_StreamTriad", softgi::bench::BM_StreamTriad)->Arg(2)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();
  for (const bool blocks : {false, true})
    benchmark::RegisterBenchmark(blocks ? "BM_HostCopy/context" : "BM_HostCopy/memcpy", [blocks](benchmark::State& st) { BM_HostCopy(st, blocks); })
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (const char* scene_name : {"spheres", "character", "crowd"})
    for (const bool apply : {false, true})
      benchmark::RegisterBenchmark((std::string("BM_Upsample/") + scene_name + (apply ? "/apply" : "/weights")).c_str(),
                                   [s = std::string(scene_name), apply](benchmark::State& st) { BM_Upsample(st, s, apply); })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  for (const char* scene_name : {"spheres", "character", "crowd"})
    for (int side : {512, 1024})
      for (const char* vis : {"raster", "embree"})
        benchmark::RegisterBenchmark(
            (std::string("BM_GBuffer/") + scene_name + "/" + std::to_string(side) + "/" + vis).c_str(),
            [s = std::string(scene_name), v = std::string(vis), side](benchmark::State& st) { BM_GBuffer(st, s, v, side); })
            ->UseManualTime()
            ->Unit(benchmark::kMillisecond)
            ->MinTime(1.0);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
