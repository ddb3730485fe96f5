// Whole frames of every registered technique on every registered backend (`--backend`,
// frame_bench.hpp), on the built-in scenes spheres, character and crowd at 512 x 512: the frame
// time (Backend::render's total, one warm-up frame first, then frames 1/30 s apart so animated
// scenes pay their per-frame updates) and the host <-> device bytes each frame moves
// (FrameResult::transfer: what a discrete GPU would carry over its bus). Run as
//   ./build/bench/bench_frames [--backend=cpu,vulkan] [--benchmark_filter=...]
// Names: BM_WholeFrame/<technique>/<scene>/<backend>.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "frame_bench.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

constexpr int kFrameSide = 512;
constexpr double kStep = 1.0 / 30.0;

void BM_WholeFrame(benchmark::State& state, const std::string& technique, const std::string& scene_name, const std::string& backend) {
  render::Backend* be = softgi::bench::backend_or_skip(state, backend);
  if (!be) return;
  const scene::Scene sc = scene::make_builtin(scene_name);
  // One technique object for all frames: it keeps its cross-frame state (tables, hierarchies).
  const std::unique_ptr<render::Technique> tech = render::create_technique(technique);
  const render::ParamSet params = render::default_params(*tech);
  render::RenderRequest req;
  req.width = req.height = kFrameSide;
  req.time = 0.0;
  try {
    be->render(*tech, sc, params, req);  // warm-up: tables, hierarchy, pipelines, uploads
  } catch (const std::exception& e) {
    state.SkipWithError((technique + " failed: " + e.what()).c_str());
    return;
  }
  double up = 0.0, down = 0.0;
  for (auto _ : state) {
    req.time += kStep;
    const render::FrameResult r = be->render(*tech, sc, params, req);
    state.SetIterationTime(r.total_seconds);
    up += static_cast<double>(r.transfer.upload);
    down += static_cast<double>(r.transfer.download);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["upload_MB"] = up / n / 1e6;
  state.counters["download_MB"] = down / n / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  return softgi::bench::frame_bench_main(argc, argv, [](const std::vector<std::string>& backends) {
    for (const auto& t : render::technique_names())
      for (const std::string scene : {"spheres", "character", "crowd"})
        for (const auto& b : backends)
          benchmark::RegisterBenchmark(("BM_WholeFrame/" + t + "/" + scene + "/" + b).c_str(),
                                       [=](benchmark::State& st) { BM_WholeFrame(st, t, scene, b); })
              ->Iterations(3)
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond);
  });
}
