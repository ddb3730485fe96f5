#include "device_peak.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "frame_bench.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/shaders/bench/fma_peak_comp.h"

namespace softgi::bench {

namespace vk = backends::vulkan;

namespace {
struct Push {
  std::uint32_t iterations;
  float m, c;
};
double& device_peak_storage() {
  static double peak = 0.0;
  return peak;
}
// Steps under llvmpipe's loop limit; invocations grown until one dispatch takes kMinSeconds, so that
// a GPU runs long enough for its timestamps and clocks and lavapipe does not wait seconds.
constexpr std::uint32_t kIterations = 4096;
constexpr double kMinSeconds = 0.1;
}  // namespace

std::uint32_t device_fma_invocations(render::Backend& vulkan) {
  static std::uint32_t n = 0;
  if (n == 0) {
    std::uint32_t k = 1u << 14;
    while (device_fma_gflops(vulkan, k, kIterations).seconds < kMinSeconds && k < (1u << 26)) k *= 4;
    n = k;
  }
  return n;
}

DeviceFmaRun device_fma_gflops(render::Backend& vulkan, std::uint32_t invocations, std::uint32_t iterations) {
  auto* ctx = dynamic_cast<vk::Context*>(vulkan.device());
  if (!ctx) throw std::runtime_error("the " + vulkan.name() + " backend has no Vulkan device");
  auto pipeline = ctx->cached<vk::ComputePipeline>("bench.fma_peak", [&] {
    return std::make_shared<vk::ComputePipeline>(*ctx, std::span<const std::uint32_t>(bench_fma_peak_comp), "bench fma_peak");
  });
  vk::Buffer out = ctx->create_buffer(static_cast<VkDeviceSize>(invocations) * sizeof(float), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                      vk::MemoryKind::Device, "bench fma_peak result");
  const Push push{iterations, 0.9999999f, 1e-7f};
  const vk::SubmitResult r = ctx->submit(
      [&](vk::Recorder& rec) { rec.dispatch(*pipeline, {vk::Bind::buffer_at(0, out)}, push, pipeline->groups_x(invocations)); },
      "bench fma_peak");
  // Each chain is a <- a m + c from a0 = seed + k: a_n = p + (a0 - p) m^n with p = c / (1 - m), so the
  // twelve chains sum to 12 p + (66 + 12 seed - 12 p) m^n. 4096 float roundings of relative size
  // 6e-8 each stay far below the 1e-3 bound; a loop that stopped early (llvmpipe's loop limit) or
  // was cut short by the compiler misses it by more than that.
  std::vector<float> check(invocations);
  ctx->download(out, check.data(), check.size() * sizeof(float));
  const double m = push.m, c = push.c, p = c / (1.0 - m), mn = std::pow(m, static_cast<double>(iterations));
  for (std::uint32_t i = 0; i < invocations; i += 4099) {
    const double seed = static_cast<double>(static_cast<float>(i) * 1e-9f);
    const double expect = 12.0 * p + (66.0 + 12.0 * seed - 12.0 * p) * mn;
    if (!(std::abs(check[i] - expect) <= 1e-3 * expect))
      throw std::runtime_error("fma_peak: invocation " + std::to_string(i) + " summed its chains to " + std::to_string(check[i]) +
                               ", expected " + std::to_string(expect) + " (the loop did not run as written)");
  }
  DeviceFmaRun run;
  const bool timer_ok = r.gpu_seconds > 0.0 && r.gpu_seconds >= kTimerValidShareOfWait * r.wait_seconds;
  run.seconds = timer_ok ? r.gpu_seconds : r.wait_seconds;
  run.source = timer_ok ? "GPU timestamps" : "fence wait";
  run.gflops = static_cast<double>(invocations) * iterations * kDeviceFmaFlopsPerStep / run.seconds * 1e-9;
  return run;
}

double device_peak_gflops() {
  double& p = device_peak_storage();
  if (p <= 0.0) {
    try {
      render::Backend& b = backend_named("vulkan");
      const std::uint32_t n = device_fma_invocations(b);
      for (int i = 0; i < 3; ++i) p = std::max(p, device_fma_gflops(b, n, kIterations).gflops);
    } catch (const std::exception&) {
      p = 0.0;
    }
  }
  return p;
}

void BM_DeviceFmaPeak(benchmark::State& state) {
  render::Backend* b = backend_or_skip(state, "vulkan");
  if (!b) return;
  DeviceFmaRun best;
  try {
    const std::uint32_t n = device_fma_invocations(*b);  // pipeline creation and sizing outside the timing
    state.counters["invocations"] = n;
    for (auto _ : state) {
      const DeviceFmaRun r = device_fma_gflops(*b, n, kIterations);
      state.SetIterationTime(r.seconds);
      if (r.gflops > best.gflops) best = r;
    }
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  state.counters["GFLOP/s"] = best.gflops;
  state.SetLabel(std::string("time from ") + best.source);
  device_peak_storage() = std::max(device_peak_storage(), best.gflops);
}

}  // namespace softgi::bench
