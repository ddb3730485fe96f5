// Spherical lights (paper 001) at frame level, measured side by side in one run:
//  - BM_FmaPeak: this machine's FMA peak (bench/fma_peak.hpp), the reference for shares of peak;
//  - BM_Frame/<scene>/<variant>/<backend>: whole frames (512x512, one frame per iteration 1/30 s apart,
//    a running animation) of the variants of paper 001's frame-rate table (section 8.5): per-sphere
//    and per-object blocking with indirect light, shadows only, and the flat SL list (no hierarchy);
//    counters: frame and accumulate_indirect milliseconds, SL-receiver pairs per second, the
//    exponentials' GFLOP/s (their SH squares and products, a lower bound of the pass's arithmetic)
//    and its share of the FMA peak;
//  - BM_Memory/<scene>: the precomputed data per object (the paper: 32-150 KB) and the tables (the
//    paper: 775 KB).
// bench/README.md gives the command and the figures.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "fma_peak.hpp"
#include "frame_bench.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

constexpr int kDisplay = 512;
constexpr double kFrameStep = 1.0 / 30.0;

using softgi::bench::BM_FmaPeak;
BENCHMARK(BM_FmaPeak)->Arg(1)->Arg(2)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();

const scene::Scene& scene_named(const std::string& name) {
  static std::map<std::string, scene::Scene> scenes;
  if (!scenes.count(name)) scenes.emplace(name, scene::make_builtin(name));
  return scenes.at(name);
}

void BM_Frame(benchmark::State& state, const std::string& scene_name, const std::vector<std::string>& params, const std::string& backend) {
  render::Backend* be = softgi::bench::backend_or_skip(state, backend);
  if (!be) return;
  const scene::Scene& sc = scene_named(scene_name);
  auto tech = render::create_technique("spherical_lights");
  render::ParamSet p = render::default_params(*tech);
  for (const auto& a : params) p.set_assignment(a);
  render::RenderRequest req;
  req.width = req.height = kDisplay;
  req.time = 0.0;
  try {
    be->recycle(be->render(*tech, sc, p, req));  // warm-up: precomputation, tables, BVH, pipelines
  } catch (const std::exception& e) {
    state.SkipWithError((std::string("spherical_lights failed: ") + e.what()).c_str());
    return;
  }
  double frame = 0.0, ind = 0.0, pairs = 0.0, flops = 0.0;
  for (auto _ : state) {
    req.time += kFrameStep;
    render::FrameResult r = be->render(*tech, sc, p, req);
    frame += r.total_seconds;
    for (const auto& pr : r.passes) {
      if (pr.name != "accumulate_indirect") continue;
      ind += pr.wall_seconds;
      auto c = pr.counters.find("pairs");
      if (c != pr.counters.end()) pairs += c->second;
      auto f = pr.counters.find("exp_flops");
      if (f != pr.counters.end()) flops += f->second;
    }
    state.SetIterationTime(r.total_seconds);
    be->recycle(std::move(r));
  }
  const double frames = static_cast<double>(state.iterations());
  state.counters["frame_ms"] = frame / frames * 1e3;
  if (ind > 0.0) {
    state.counters["indirect_ms"] = ind / frames * 1e3;
    state.counters["pairs/frame"] = pairs / frames;
    state.counters["Mpairs/s"] = pairs / ind * 1e-6;
    state.counters["exp_GFLOP/s"] = flops / ind * 1e-9;
    const double peak = softgi::bench::peak_gflops();
    if (peak > 0.0) state.counters["exp_share_of_peak"] = flops / ind * 1e-9 / peak;
  }
}

// Bytes of the per-object precomputation (sl_setup's record divided by its objects) and of the
// tables pass (cap log ZH, OL tables, w_theta).
void BM_Memory(benchmark::State& state, const std::string& scene_name) {
  render::Backend* be = softgi::bench::backend_or_skip(state, "cpu");
  if (!be) return;
  const scene::Scene& sc = scene_named(scene_name);
  auto tech = render::create_technique("spherical_lights");
  const render::ParamSet p = render::default_params(*tech);
  render::RenderRequest req;
  req.width = req.height = 16;
  double per_object = 0.0, tables = 0.0, weight = 0.0;
  for (auto _ : state) {
    const render::FrameResult r = be->render(*tech, sc, p, req);
    for (const auto& pr : r.passes) {
      if (pr.name == "sl_setup") per_object = static_cast<double>(pr.bytes) / std::max(1.0, pr.counters.at("objects"));
      if (pr.name == "tables") {
        tables = static_cast<double>(pr.bytes);
        weight = pr.counters.at("weight_table_bytes");
      }
    }
  }
  state.counters["KB_per_object"] = per_object / 1024.0;
  state.counters["tables_KB"] = tables / 1024.0;
  state.counters["w_theta_KB"] = weight / 1024.0;
}

}  // namespace

// --backend=cpu|vulkan|both (default both): BM_Frame/<scene>/<variant>/<backend> on `assembly` (6
// objects) and `crowd` (10 objects, 414 SLs).
int main(int argc, char** argv) {
  return softgi::bench::frame_bench_main(argc, argv, [](const std::vector<std::string>& backends) {
    struct Variant {
      const char* name;
      std::vector<std::string> params;
    };
    const std::vector<Variant> variants = {{"per_sphere", {}},
                                           {"per_object", {"blocking=per_object"}},
                                           {"shadows_only", {"indirect=false"}},
                                           {"flat", {"hierarchy=false"}}};
    for (const std::string scene : {"assembly", "crowd"})
      for (const auto& b : backends)
        for (const auto& v : variants) {
          if (scene == "crowd" && std::string(v.name) == "flat") continue;  // seconds per frame: the quadratic cost
          benchmark::RegisterBenchmark(("BM_Frame/" + scene + "/" + v.name + "/" + b).c_str(),
                                       [=](benchmark::State& st) { BM_Frame(st, scene, v.params, b); })
              ->Iterations(3)
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond);
        }
    for (const std::string scene : {"sphere_plane", "box8", "bunny", "assembly", "crowd"})
      benchmark::RegisterBenchmark(("BM_Memory/" + scene).c_str(), [=](benchmark::State& st) { BM_Memory(st, scene); })
          ->Iterations(1)
          ->Unit(benchmark::kMillisecond);
  });
}
