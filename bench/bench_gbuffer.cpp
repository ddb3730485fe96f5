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
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <string>

#include "softgi/backends/cpu_backend.hpp"
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

}  // namespace

int main(int argc, char** argv) {
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
