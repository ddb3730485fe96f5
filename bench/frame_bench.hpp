// Frame-level benchmarks on both backends (bench_image_splat, bench_shexp): the `--backend` flag, one
// backend object of each kind per process, and the accumulation passes' throughput read from the pass
// records: receiver-blocker pairs per second and GFLOP/s of accumulate_log with SHEXP's flop model
// (shexp::kernel_flops_per_pair, the same on both backends because the GLSL kernel follows the CPU
// kernel's arithmetic), receivers per second and GFLOP/s of exponentiate, and shares of the FMA peak.
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../techniques/shexp/shexp_internal.hpp"
#include "bandwidth.hpp"
#include "device_peak.hpp"
#include "fma_peak.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/techniques/registry.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::bench {

// Every backend and technique this build has, registered once.
inline void register_builtin() {
  backends::register_cpu_backend();
  backends::register_vulkan_backend();
  techniques::register_vulkan_kernels();
}

// `--backend=NAME[,NAME...]|all` (default all: every registered backend), taken out of argv before
// benchmark::Initialize sees it.
inline std::vector<std::string> take_backend_flag(int& argc, char** argv) {
  register_builtin();
  std::string v = "all";
  int out = 1;
  for (int i = 1; i < argc; ++i) {
    const char* a = argv[i];
    if (std::strncmp(a, "--backend=", 10) == 0) {
      v = a + 10;
      continue;
    }
    argv[out++] = argv[i];
  }
  argc = out;
  argv[argc] = nullptr;
  if (v == "all" || v == "both") return render::backend_names();
  std::vector<std::string> names;
  for (std::size_t pos = 0; pos <= v.size();) {
    const std::size_t end = std::min(v.find(',', pos), v.size());
    const std::string name = v.substr(pos, end - pos);
    render::backend_info(name);  // unknown: the registry's error lists the registered ones
    names.push_back(name);
    pos = end + 1;
  }
  return names;
}

// One backend object per name and process: a device backend owns the instance, device and the GPU
// objects cached across frames (pipelines, uploaded tables), so every benchmark shares it. A failed
// creation is remembered and rethrown (same message) for each later request.
inline render::Backend& backend_named(const std::string& name) {
  static std::map<std::string, std::unique_ptr<render::Backend>> made;
  static std::map<std::string, std::string> errors;
  auto it = made.find(name);
  if (it != made.end()) return *it->second;
  if (!errors.count(name)) {
    try {
      auto b = render::create_backend(name);
      const auto d = b->device_record();
      if (!d.empty()) std::fprintf(stderr, "%s device: %s\n", name.c_str(), d.at("name").c_str());
      return *made.emplace(name, std::move(b)).first->second;
    } catch (const std::exception& e) {
      errors[name] = e.what();
    }
  }
  throw std::runtime_error("no " + name + " backend: " + errors[name]);
}

// The backend, or null with the benchmark skipped, naming why the backend cannot run.
inline render::Backend* backend_or_skip(benchmark::State& state, const std::string& name) {
  register_builtin();
  try {
    return &backend_named(name);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return nullptr;
  }
}

// Where a pass's kernel time came from.
enum class TimeSource { HostKernelTimer, GpuTimestamp, FenceWait, PassWall };
inline const char* to_string(TimeSource s) {
  switch (s) {
    case TimeSource::HostKernelTimer: return "host kernel timer";
    case TimeSource::GpuTimestamp: return "GPU timestamps";
    case TimeSource::FenceWait: return "fence wait";
    case TimeSource::PassWall: return "pass wall";
  }
  return "?";
}

// A GPU pass's kernel timer (kernel_gpu_seconds, timestamps around the dispatches) is trusted when it
// is at least this share of the fence wait of the pass's submissions (gpu_wait_seconds, which holds
// the same dispatches plus submission and fence overhead). On lavapipe, after a graphics pass, the
// timestamps collapse to 0.06-0.2 ms against 22-33 ms of fence wait (a share below 0.01; see
// docs/backends.md), while valid timestamps on a compute-only context are within a few per cent of
// the wait: 0.5 separates the two cases with a wide margin on either side.
inline constexpr double kTimerValidShareOfWait = 0.5;

// The kernel seconds of one pass record, and where they came from. CPU passes that count pairs time
// their kernel loop alone (pairs / pairs_per_second); GPU passes carry kernel_gpu_seconds and
// gpu_wait_seconds (the Vulkan backend's record); anything else falls back to the pass wall time.
inline double kernel_seconds(const render::PassRecord& p, TimeSource& src) {
  auto get = [&](const char* k) {
    auto it = p.counters.find(k);
    return it == p.counters.end() ? -1.0 : it->second;
  };
  const double timer = get("kernel_gpu_seconds"), wait = get("gpu_wait_seconds");
  if (p.counters.count("kernel_gpu_seconds")) {
    if (timer > 0.0 && (wait <= 0.0 || timer >= kTimerValidShareOfWait * wait)) {
      src = TimeSource::GpuTimestamp;
      return timer;
    }
    if (wait > 0.0) {
      src = TimeSource::FenceWait;
      return wait;
    }
  }
  const double pairs = get("pairs"), pps = get("pairs_per_second");
  if (pairs > 0.0 && pps > 0.0) {
    src = TimeSource::HostKernelTimer;
    return pairs / pps;
  }
  src = TimeSource::PassWall;
  return p.wall_seconds;
}

// Sums over the timed frames for one pass.
struct PassSums {
  double kernel = 0.0, wall = 0.0, pairs = 0.0, receivers = 0.0, squares = 0.0, products = 0.0;
  bool counts_squares = true;  // every frame's record carried squares (and products) counts
  std::map<TimeSource, int> sources;
  int frames = 0;
  void add(const render::PassRecord& p) {
    TimeSource src{};
    kernel += kernel_seconds(p, src);
    ++sources[src];
    wall += p.wall_seconds;
    auto get = [&](const char* k) {
      auto it = p.counters.find(k);
      return it == p.counters.end() ? 0.0 : it->second;
    };
    pairs += get("pairs");
    receivers += get("receivers");
    if (p.counters.count("squares") || p.counters.count("squarings")) {
      squares += p.counters.count("squares") ? get("squares") : get("squarings");
      products += get("products");
    } else {
      counts_squares = false;
    }
    ++frames;
  }
  std::string source() const {
    std::string s;
    for (const auto& [k, n] : sources) {
      if (!s.empty()) s.append("+");
      s.append(to_string(k));
      if (sources.size() > 1) s.append(" x").append(std::to_string(n));  // frames that used it
    }
    return s;
  }
};

// One row of the summary table printed after the run.
struct Row {
  // backend: the registered name (it selects the peak the shares are of); variant: what the
  // benchmark changed on it ("avx2", "(no frame pool)"), printed after it.
  std::string bench, scene, technique, backend, variant, pass, source;
  std::string backend_label() const { return variant.empty() ? backend : backend + " " + variant; }
  double ms = 0.0, wall_ms = 0.0, mrate = 0.0, gflops = -1.0, share = -1.0, share_hi = -1.0;
  const char* unit = "Mpairs/s";
};
inline std::vector<Row>& rows() {
  static std::vector<Row> r;
  return r;
}

// Flop model of the accumulation passes (see the file comment).
struct FlopModel {
  int acc_order = 4;  // order of the log vectors (accumulate_log, exponentiate)
  techniques::shexp::ReplacementRule rule = techniques::shexp::ReplacementRule::Continuous;
};

// Counters for accumulate_log ("log_") and exponentiate ("exp_"), and a summary row for each.
// Shares of peak are taken against the peak of the device the pass ran on: the CPU's FMA peak
// (BM_FmaPeak) for the CPU backend, the Vulkan device's (BM_DeviceFmaPeak, a GLSL FMA loop) for the
// Vulkan backend's GPU passes.
inline void report_passes(benchmark::State& state, const std::map<std::string, PassSums>& sums, const FlopModel& fm, Row base) {
  namespace sx = techniques::shexp;
  // A Vulkan row without a measured device peak gets no share (-1), never one of the CPU's peak.
  const bool on_device = base.backend != "cpu";
  const double peak = on_device ? device_peak_gflops() : peak_gflops();
  auto share_of = [peak](double gflops) { return peak > 0.0 ? gflops / peak : -1.0; };
  state.counters["peak_GFLOP/s"] = peak;
  std::string label;
  auto it = sums.find("accumulate_log");
  if (it != sums.end() && it->second.kernel > 0.0 && it->second.frames > 0) {
    const PassSums& s = it->second;
    const double rate = s.pairs / s.kernel;
    const double fast = sx::kernel_flops_per_pair(fm.acc_order, fm.rule, false), straddle = sx::kernel_flops_per_pair(fm.acc_order, fm.rule, true);
    state.counters["log_ms"] = s.kernel / s.frames * 1e3;
    state.counters["log_wall_ms"] = s.wall / s.frames * 1e3;
    state.counters["log_pairs/frame"] = s.pairs / s.frames;
    state.counters["log_Mpairs/s"] = rate * 1e-6;
    state.counters["log_GFLOP/s"] = rate * fast * 1e-9;
    state.counters["log_share_fast"] = share_of(rate * fast * 1e-9);
    state.counters["log_share_straddle"] = share_of(rate * straddle * 1e-9);
    Row r = base;
    r.pass = "accumulate_log";
    r.source = s.source();
    r.ms = s.kernel / s.frames * 1e3;
    r.wall_ms = s.wall / s.frames * 1e3;
    r.mrate = rate * 1e-6;
    r.gflops = rate * fast * 1e-9;
    r.share = share_of(r.gflops);
    r.share_hi = share_of(rate * straddle * 1e-9);
    rows().push_back(r);
    label.append("log: ").append(r.source);
  }
  it = sums.find("exponentiate");
  if (it != sums.end() && it->second.kernel > 0.0 && it->second.frames > 0) {
    const PassSums& s = it->second;
    Row r = base;
    r.pass = "exponentiate";
    r.unit = "Mrec/s";
    r.source = s.source();
    r.ms = s.kernel / s.frames * 1e3;
    r.wall_ms = s.wall / s.frames * 1e3;
    r.mrate = s.receivers / s.kernel * 1e-6;
    state.counters["exp_ms"] = r.ms;
    state.counters["exp_wall_ms"] = r.wall_ms;
    state.counters["exp_Mrec/s"] = r.mrate;
    // The squares and products the pass made, each at TripleProduct's flop count (the dominant
    // work of HYB/OL); the OL evaluation and element-wise loops are not counted: a lower bound.
    // Only where the record counts them (both SHEXP backends; image_splat's CPU pass does not).
    if (s.counts_squares && s.squares + s.products > 0.0) {
      const sh::TripleProduct& tp = sh::TripleProduct::get(fm.acc_order);
      const double flops = s.squares * static_cast<double>(tp.square_flops()) + s.products * static_cast<double>(tp.product_flops());
      r.gflops = flops / s.kernel * 1e-9;
      r.share = share_of(r.gflops);
      state.counters["exp_GFLOP/s"] = r.gflops;
      state.counters["exp_share"] = r.share;
    }
    rows().push_back(r);
    if (!label.empty()) label.append(", ");
    label.append("exp: ").append(r.source);
  }
  state.SetLabel(label);
}

// Display-resolution passes against the memory bandwidth (bandwidth.hpp): one row per pass with a
// byte model, from the mean wall time of the timed frames.
struct BandwidthRow {
  std::string bench, scene, backend, variant, pass;  // as Row
  std::string backend_label() const { return variant.empty() ? backend : backend + " " + variant; }
  double ms = 0.0, mbytes = 0.0, gbps = 0.0, share = 0.0;
};
inline std::vector<BandwidthRow>& bandwidth_rows() {
  static std::vector<BandwidthRow> r;
  return r;
}
// `wall`: each pass's wall seconds summed over `frames` frames of width x height; `moved`: the
// "bytes_moved" counters the passes recorded, summed the same way. A pass's own count is used where
// it records one, else the byte model (bandwidth.hpp).
inline void report_display_passes(benchmark::State& state, const std::map<std::string, double>& wall,
                                  const std::map<std::string, double>& moved, int frames, int width, int height, const Row& base) {
  const double bw = bandwidth_gbps();
  for (const auto& [pass, seconds] : wall) {
    const auto own = moved.find(pass);
    const double bytes = own != moved.end() && frames > 0 ? own->second / frames : display_pass_bytes(pass, width, height);
    if (bytes <= 0.0 || seconds <= 0.0 || frames <= 0) continue;
    BandwidthRow r;
    r.bench = base.bench;
    r.scene = base.scene;
    r.backend = base.backend;
    r.variant = base.variant;
    r.pass = pass;
    r.ms = seconds / frames * 1e3;
    r.mbytes = bytes * 1e-6;
    r.gbps = bytes / (seconds / frames) * 1e-9;
    r.share = r.gbps / bw;
    state.counters[pass + "_GB/s"] = r.gbps;
    state.counters[pass + "_bw_share"] = r.share;
    bandwidth_rows().push_back(r);
  }
}

// The summary table (markdown), printed after the benchmarks.
inline void print_rows() {
  if (!bandwidth_rows().empty()) {
    std::printf("\n| bench | scene | backend | display pass | wall ms/frame | MB moved (lower bound) | GB/s | share of the triad bandwidth |\n");
    std::printf("|---|---|---|---|---|---|---|---|\n");
    for (const BandwidthRow& r : bandwidth_rows())
      std::printf("| %s | %s | %s | %s | %.2f | %.1f | %.2f | %.3f |\n", r.bench.c_str(), r.scene.c_str(), r.backend_label().c_str(), r.pass.c_str(),
                  r.ms, r.mbytes, r.gbps, r.share);
    std::printf("\nSTREAM triad: %.1f GB/s on 2 threads (the bandwidth rows' reference; 12 bytes per element)\n", bandwidth_gbps());
  }
  if (rows().empty()) return;
  std::printf("\n| bench | scene | backend | pass | kernel ms/frame | pass wall ms | rate | GFLOP/s | share of the device's FMA peak | time from |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : rows()) {
    char gf[32] = "-", sh[48] = "-";
    if (r.gflops >= 0.0) std::snprintf(gf, sizeof gf, "%.2f", r.gflops);
    if (r.share >= 0.0 && r.share_hi >= 0.0)
      std::snprintf(sh, sizeof sh, "%.3f-%.3f", r.share, r.share_hi);
    else if (r.share >= 0.0)
      std::snprintf(sh, sizeof sh, ">= %.3f", r.share);
    std::printf("| %s | %s | %s | %s | %.2f | %.2f | %.2f %s | %s | %s | %s |\n", r.bench.c_str(), r.scene.c_str(), r.backend_label().c_str(), r.pass.c_str(),
                r.ms, r.wall_ms, r.mrate, r.unit, gf, sh, r.source.c_str());
  }
  double one = 0.0;  // best of five, as the 2-thread figure
  for (int i = 0; i < 5; ++i) one = std::max(one, fma_gflops(1, 20'000'000));
  const double two = peak_gflops();
  std::printf("\nFMA peak: %.1f GFLOP/s on 2 threads (the CPU rows' reference), %.1f on 1 thread\n", two, one);
  bool vulkan_rows = false;
  for (const Row& r : rows()) vulkan_rows |= r.backend != "cpu";
  if (vulkan_rows)
    std::printf("Vulkan device FMA peak (GLSL loop, BM_DeviceFmaPeak): %.1f GFLOP/s (the Vulkan rows' reference), %.2fx the CPU's\n",
                device_peak_gflops(), device_peak_gflops() / two);
  // Two threads on two cores run at about twice one thread; a 2-thread peak below this multiple of
  // the 1-thread figure means other processes held a core while it was measured (or the two CPUs
  // are hyperthreads of one core), and the shares above are inflated by up to that factor.
  constexpr double kMinTwoThreadScaling = 1.5;
  if (two < kMinTwoThreadScaling * one)
    std::printf("WARNING: the 2-thread FMA peak is only %.2fx the 1-thread one: the machine was busy (or has one physical core); "
                "shares of peak are not reliable in this run\n", two / one);
}

// main() of a frame-level benchmark: --backend, then Google Benchmark, then the table.
template <class Register>
int frame_bench_main(int argc, char** argv, Register register_benchmarks) {
  std::vector<std::string> backends;
  try {
    backends = take_backend_flag(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  if (std::find(backends.begin(), backends.end(), "vulkan") != backends.end())
    benchmark::RegisterBenchmark("BM_DeviceFmaPeak", BM_DeviceFmaPeak)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
  register_benchmarks(backends);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  print_rows();
  return 0;
}

}  // namespace softgi::bench
