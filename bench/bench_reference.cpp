// Ground-truth renderer throughput (docs/reference.md, "Measurements"): one render of a built-in
// scene at 128x128 with 4 samples per pixel per iteration, setup (posing, BVH builds, environment
// tables) included. Counters: pixel samples and rays per second.
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "softgi/io/scene_file.hpp"
#include "softgi/reference/reference.hpp"

namespace {

using softgi::reference::ReferenceOptions;

const std::vector<std::string> kScenes = {"spheres", "cornell", "character", "crowd"};

// range(0): scene index; range(1): 0 = real geometry, 1 = proxies; range(2): 0 = full light, n = SH order.
void BM_Reference(benchmark::State& state) {
  const std::string name = kScenes[static_cast<std::size_t>(state.range(0))];
  const softgi::scene::Scene sc = softgi::io::load_scene(name);
  ReferenceOptions opt;
  opt.spp = 4;
  opt.width = opt.height = 128;
  opt.blockers = state.range(1) ? ReferenceOptions::Blockers::Proxies : ReferenceOptions::Blockers::Geometry;
  opt.light_sh_order = static_cast<int>(state.range(2));
  long long rays = 0, samples = 0;
  for (auto _ : state) {
    const auto r = softgi::reference::render_reference(sc, opt);
    rays += r.rays;
    samples += static_cast<long long>(r.final_image.width) * r.final_image.height * opt.spp;
    benchmark::DoNotOptimize(r.final_image.rgb.data());
  }
  state.SetLabel(name + (state.range(1) ? " proxies" : " geometry") +
                 (state.range(2) ? " sh" + std::to_string(state.range(2)) : std::string(" full")));
  state.counters["samples/s"] = benchmark::Counter(static_cast<double>(samples), benchmark::Counter::kIsRate);
  state.counters["rays/s"] = benchmark::Counter(static_cast<double>(rays), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Reference)
    ->ArgsProduct({{0, 1, 2, 3}, {0}, {0}})
    ->Args({0, 1, 0})
    ->Args({0, 0, 4})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
