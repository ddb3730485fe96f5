// Image-space proxy accumulation (paper 000) throughput, measured on the technique's own passes:
//  - BM_FmaPeak: this machine's FMA peak (bench/fma_peak.hpp), the reference for shares of peak;
//  - BM_Accumulation/<scene>/<backend>/<kernel>: 1024x1024 display with receiver_scale = 4 (a
//    256x256 receiver buffer, the paper's setting for Figure 6), one frame per iteration 1/30 s apart
//    (a running animation), on the CPU or the Vulkan backend (`--backend`, frame_bench.hpp). From the
//    pass records: accumulate_log's receiver-proxy pairs per second (pairs = receivers of each tile x
//    proxies binned to the tile, as the passes count them), GFLOP/s and share of the FMA peak using
//    SHEXP's flop model (techniques::common::kernel_flops_per_pair: the log kernel is SHEXP's kernel, on the GPU
//    SHEXP's shader). Two shares are given: with the rules' fast path for every pair (proxies entirely
//    in front of the receiver's tangent plane, most pairs here) and with the straddling-case count for
//    every pair; the true share lies between them. exponentiate: receivers per second; and
//    accumulate_indirect's pairs per second (host on both backends). The manual iteration time is
//    the sum of these three passes' wall times.
#include <benchmark/benchmark.h>

#include <exception>
#include <map>
#include <string>
#include <vector>

#include "../techniques/common/accumulation.hpp"
#include "fma_peak.hpp"
#include "frame_bench.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/registry.hpp"

namespace {

using namespace softgi;
namespace sx = softgi::techniques::common;

constexpr int kDisplay = 1024;       // paper 000 section 6: renderings at 1024x1024
constexpr int kReceiverScale = 4;    // 256x256 receiver buffer
constexpr double kFrameStep = 1.0 / 30.0;

using softgi::bench::BM_FmaPeak;
BENCHMARK(BM_FmaPeak)->Arg(1)->Arg(2)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();

const char* const kKernels[] = {"auto", "avx512", "avx2", "scalar"};

// One frame-level run: `scene` on `backend` with the CPU kernel `kernel` (on Vulkan the kernel
// parameter only reaches the passes that stay on the host).
void BM_Accumulation(benchmark::State& state, const std::string& scene_name, const std::string& backend, const std::string& kernel) {
  const sx::KernelIsa isa = kernel == "avx512" ? sx::KernelIsa::Avx512
                            : kernel == "avx2" ? sx::KernelIsa::Avx2
                            : kernel == "scalar" ? sx::KernelIsa::Scalar
                                                 : sx::best_kernel_isa();
  if (!sx::kernel_isa_supported(isa)) {
    state.SkipWithError("this CPU cannot run this kernel");
    return;
  }
  render::Backend* be = softgi::bench::backend_or_skip(state, backend);
  if (!be) return;
  static std::map<std::string, scene::Scene> scenes;
  if (!scenes.count(scene_name)) scenes.emplace(scene_name, scene::make_builtin(scene_name));
  const scene::Scene& sc = scenes.at(scene_name);
  auto tech = render::create_technique("image_splat");
  render::ParamSet params = render::default_params(*tech);
  params.set("receiver_scale", std::to_string(kReceiverScale));
  params.set("kernel", kernel);
  softgi::bench::FlopModel fm;
  fm.acc_order = params.get_int("order");
  // The rule the passes apply (shexp's flop model depends on it).
  if (params.has("replacement_rule")) fm.rule = sx::parse_replacement_rule(params.get_enum("replacement_rule"));
  if (params.has("self_shadow_rules") && !params.get_bool("self_shadow_rules")) fm.rule = sx::ReplacementRule::Off;
  render::RenderRequest req;
  req.width = req.height = kDisplay;
  req.time = 0.0;
  try {
    be->recycle(be->render(*tech, sc, params, req));  // warm-up: tables, eta derivations, BVH, pipelines
  } catch (const std::exception& e) {
    state.SkipWithError((std::string("image_splat failed: ") + e.what()).c_str());
    return;
  }

  std::map<std::string, softgi::bench::PassSums> sums;
  double ind_secs = 0.0, ind_pairs = 0.0, inside = 0.0;
  for (auto _ : state) {
    req.time += kFrameStep;
    render::FrameResult r = be->render(*tech, sc, params, req);
    double t = 0.0;
    for (const auto& p : r.passes) {
      if (p.name == "accumulate_log" || p.name == "exponentiate") {
        sums[p.name].add(p);
        t += p.wall_seconds;
      }
      if (p.name != "accumulate_indirect") continue;
      ind_secs += p.wall_seconds;
      t += p.wall_seconds;
      auto c = p.counters.find("pairs");
      if (c != p.counters.end()) ind_pairs += c->second;
      auto in = p.counters.find("pairs_inside_influence");
      if (in != p.counters.end()) inside += in->second;
    }
    state.SetIterationTime(t);
    be->recycle(std::move(r));
  }
  if (sums["accumulate_log"].pairs <= 0.0) {
    state.SkipWithError("the frame ran no accumulate_log pass with pairs (pass names or counters changed?)");
    return;
  }
  const double frames = static_cast<double>(state.iterations());
  state.counters["receivers"] = sums["accumulate_log"].receivers / frames;
  softgi::bench::Row base;
  base.bench = "image_splat";
  base.scene = scene_name;
  base.technique = "image_splat";
  base.backend = backend;
  if (backend == backends::cpu::kBackendName) base.variant.append(kernel).append(kernel == "auto" ? " = " : "").append(kernel == "auto" ? sx::to_string(isa) : "");
  softgi::bench::report_passes(state, sums, fm, base);
  if (ind_secs > 0.0) {
    state.counters["ind_pairs/frame"] = ind_pairs / frames;
    state.counters["ind_inside/frame"] = inside / frames;
    state.counters["ind_ms"] = ind_secs / frames * 1e3;
    state.counters["ind_Mpairs/s"] = ind_pairs / ind_secs * 1e-6;
  }
}

}  // namespace

// --backend=cpu|vulkan|both (default both), parsed before benchmark::Initialize: names are
// BM_Accumulation/<scene>/<backend>/<kernel>; the CPU runs every kernel instruction set on
// `character` and `auto` on `crowd`, Vulkan runs once per scene.
int main(int argc, char** argv) {
  return softgi::bench::frame_bench_main(argc, argv, [](const std::vector<std::string>& backends) {
    for (const std::string scene : {"character", "crowd"})
      for (const auto& b : backends)
        for (const std::string k : kKernels) {
          if (k != "auto" && (b != backends::cpu::kBackendName || scene != "character")) continue;
          benchmark::RegisterBenchmark(("BM_Accumulation/" + scene + "/" + b + "/" + k).c_str(),
                                       [=](benchmark::State& st) { BM_Accumulation(st, scene, b, k); })
              ->Iterations(5)
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond);
        }
  });
}
