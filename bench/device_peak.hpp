// The Vulkan device's single-precision FMA peak, measured by a GLSL FMA loop (shaders/bench/
// fma_peak.comp) on the device the Vulkan backend runs on, so that a GPU pass's GFLOP/s is a share
// of what that device (lavapipe on a CPU, or a GPU) can do, measured in the same run.
#pragma once

#include <benchmark/benchmark.h>

#include "softgi/render/backend.hpp"

namespace softgi::bench {

// FLOPs per invocation and step of the shader: 12 chains x 2 (an FMA is two operations).
inline constexpr double kDeviceFmaFlopsPerStep = 24.0;

struct DeviceFmaRun {
  double gflops = 0.0;
  double seconds = 0.0;  // the dispatch, from GPU timestamps where they are valid, else the fence wait
  const char* source = "";
};
// One dispatch of `invocations` x `iterations` on the backend's device (its render::Device must be
// the Vulkan backend's context). Throws std::runtime_error when the backend has no Vulkan device or the
// result is not finite (the loop did not run as written).
DeviceFmaRun device_fma_gflops(render::Backend& vulkan, std::uint32_t invocations, std::uint32_t iterations);

// Invocations per dispatch for the peak: grown by 4x from 2^14 until a 4096-step dispatch takes
// 0.1 s (at most 2^26); measured once per process.
std::uint32_t device_fma_invocations(render::Backend& vulkan);

// The peak the Vulkan rows' shares are taken against: the best BM_DeviceFmaPeak iteration of this
// run, measured on first use when that benchmark did not run. 0 when there is no Vulkan device.
double device_peak_gflops();

// BM_DeviceFmaPeak: the best of its iterations, counters GFLOP/s and the time source; records the peak.
void BM_DeviceFmaPeak(benchmark::State& state);

}  // namespace softgi::bench
