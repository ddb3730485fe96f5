// The comparative benchmark suite: every registered technique on every built-in scene on every
// registered backend, at default settings. Each benchmark renders one untimed warm-up frame (tables,
// hierarchies, pipelines, uploads), then frames 1/30 s apart so animated scenes pay their per-frame
// updates; the time is Backend::render's total. Counters: the mean wall time of every pass
// ("ms:<pass>"), the host <-> device bytes per frame and the passes the graph left out. After the
// run, one table of medians per scene and backend with each technique's time over the fastest one's.
//   ./build/bench/bench_techniques [--backend=cpu,vulkan] [--scenes=spheres,crowd] [--size=512]
//       [--variants=image_splat:binning=device,...]
//       [--benchmark_filter=...] [--benchmark_repetitions=N] [--benchmark_out=F --benchmark_out_format=json]
// Names: BM_Technique/<scene>/<backend>/<technique>. A variant (one parameter of one technique set
// away from its default) runs beside the default as BM_Technique/<scene>/<backend>/<technique>[name=value],
// so that the two are measured side by side in one run.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "frame_bench.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

constexpr double kStep = 1.0 / 30.0;

// Frame times of every run of one benchmark (all repetitions), for the median table.
using Key = std::tuple<std::string, std::string, std::string>;  // scene, backend, technique
struct Times {
  std::vector<double> frames;
  std::string slowest_pass;
  double slowest_ms = 0.0;
  std::string error;
};
std::map<Key, Times>& times() {
  static std::map<Key, Times> t;
  return t;
}

// A technique at its defaults (assignment empty) or with parameters set: "name=value", several
// joined by '+' ("receiver_scale=4+indirect=false").
struct Variant {
  std::string technique, assignment;
  std::string label() const { return assignment.empty() ? technique : technique + "[" + assignment + "]"; }
  void apply(render::ParamSet& p) const {
    std::size_t start = 0;
    while (start < assignment.size()) {
      const std::size_t plus = assignment.find('+', start);
      const std::size_t end = plus == std::string::npos ? assignment.size() : plus;
      p.set_assignment(assignment.substr(start, end - start));
      start = end + 1;
    }
  }
};

void BM_Technique(benchmark::State& state, const std::string& scene_name, const std::string& backend, const Variant& variant,
                  int side) {
  const std::string& technique = variant.technique;
  Times& out = times()[Key{scene_name, backend, variant.label()}];
  render::Backend* be = softgi::bench::backend_or_skip(state, backend);
  if (!be) {
    out.error = "backend unavailable";
    return;
  }
  scene::Scene sc;
  try {
    sc = scene::make_builtin(scene_name);
  } catch (const std::exception& e) {
    out.error = e.what();
    state.SkipWithError(("scene " + scene_name + ": " + e.what()).c_str());
    return;
  }
  // One technique object for all frames: it keeps its cross-frame state.
  const std::unique_ptr<render::Technique> tech = render::create_technique(technique);
  render::ParamSet params = render::default_params(*tech);
  variant.apply(params);
  render::RenderRequest req;
  req.width = req.height = side;
  req.time = 0.0;
  try {
    be->recycle(be->render(*tech, sc, params, req));
  } catch (const std::exception& e) {
    out.error = e.what();
    state.SkipWithError((technique + " failed: " + e.what()).c_str());
    return;
  }
  std::map<std::string, double> pass_seconds;
  double up = 0.0, down = 0.0, pruned = 0.0, faults = 0.0;
  for (auto _ : state) {
    req.time += kStep;
    render::FrameResult r = be->render(*tech, sc, params, req);
    state.SetIterationTime(r.total_seconds);
    out.frames.push_back(r.total_seconds);
    for (const auto& p : r.passes) {
      pass_seconds[p.name] += p.wall_seconds;
      faults += static_cast<double>(std::max(p.page_faults, 0LL));
    }
    up += static_cast<double>(r.transfer.upload);
    down += static_cast<double>(r.transfer.download);
    pruned = static_cast<double>(r.pruned.size());
    be->recycle(std::move(r));  // as a caller rendering a sequence does: the next frame reuses its buffers
  }
  const double n = static_cast<double>(state.iterations());
  for (const auto& [name, s] : pass_seconds) {
    state.counters["ms:" + name] = s / n * 1e3;
    if (s / n * 1e3 > out.slowest_ms) {
      out.slowest_ms = s / n * 1e3;
      out.slowest_pass = name;
    }
  }
  state.counters["upload_MB"] = up / n / 1e6;
  state.counters["download_MB"] = down / n / 1e6;
  state.counters["pruned_passes"] = pruned;
  // Fresh memory touched by the timed frames' passes: 0 once every per-frame buffer is recycled.
  state.counters["page_faults/frame"] = faults / n;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// Per scene and backend: every technique's median frame time, and its ratio to the fastest one.
void print_table() {
  if (times().empty()) return;
  std::printf("\n| scene | backend | technique | median ms | x fastest | slowest pass (mean ms) |\n|---|---|---|---|---|---|\n");
  std::map<std::pair<std::string, std::string>, double> fastest;
  for (const auto& [k, t] : times()) {
    if (t.frames.empty()) continue;
    const auto g = std::make_pair(std::get<0>(k), std::get<1>(k));
    const double m = median(t.frames);
    auto it = fastest.find(g);
    if (it == fastest.end() || m < it->second) fastest[g] = m;
  }
  for (const auto& [k, t] : times()) {
    const auto& [scene, backend, technique] = k;
    if (t.frames.empty()) {
      std::printf("| %s | %s | %s | - | - | not run: %s |\n", scene.c_str(), backend.c_str(), technique.c_str(),
                  t.error.empty() ? "filtered out" : t.error.c_str());
      continue;
    }
    const double m = median(t.frames);
    std::printf("| %s | %s | %s | %.2f | %.2f | %s (%.2f) |\n", scene.c_str(), backend.c_str(), technique.c_str(), m * 1e3,
                m / fastest.at({scene, backend}), t.slowest_pass.c_str(), t.slowest_ms);
  }
}

// Takes `--NAME=VALUE` out of argv (before Google Benchmark sees it); returns false if absent.
bool take_flag(int& argc, char** argv, const char* name, std::string& value) {
  const std::string prefix = std::string("--") + name + "=";
  bool found = false;
  int out = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], prefix.c_str(), prefix.size()) == 0) {
      value = argv[i] + prefix.size();
      found = true;
      continue;
    }
    argv[out++] = argv[i];
  }
  argc = out;
  argv[argc] = nullptr;
  return found;
}

std::vector<std::string> split(const std::string& v) {
  std::vector<std::string> out;
  for (std::size_t pos = 0; pos <= v.size();) {
    const std::size_t end = std::min(v.find(',', pos), v.size());
    if (end > pos) out.push_back(v.substr(pos, end - pos));
    pos = end + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> scenes;
  for (const auto& b : scene::builtin_scenes()) scenes.push_back(b.name);
  int side = 512;
  std::string v;
  if (take_flag(argc, argv, "scenes", v)) {
    scenes = split(v);
    for (const auto& s : scenes) {
      bool known = false;
      for (const auto& b : scene::builtin_scenes()) known |= b.name == s;
      if (!known) {
        std::string names;
        for (const auto& b : scene::builtin_scenes()) names += (names.empty() ? "" : ", ") + b.name;
        std::fprintf(stderr, "--scenes: unknown built-in scene '%s' (known: %s)\n", s.c_str(), names.c_str());
        return 2;
      }
    }
  }
  if (take_flag(argc, argv, "size", v)) {
    char* end = nullptr;
    const long n = std::strtol(v.c_str(), &end, 10);
    if (end == v.c_str() || *end != '\0' || n < 8 || n > 8192) {
      std::fprintf(stderr, "--size: '%s' is not a side length in [8, 8192]\n", v.c_str());
      return 2;
    }
    side = static_cast<int>(n);
  }
  softgi::bench::register_builtin();  // the techniques the variants name
  std::vector<Variant> variants;
  for (const auto& t : render::technique_names()) variants.push_back(Variant{t, ""});
  if (take_flag(argc, argv, "variants", v)) {
    for (const auto& item : split(v)) {
      const std::size_t colon = item.find(':');
      const std::string tech = item.substr(0, colon);
      const auto& names = render::technique_names();
      if (colon == std::string::npos || std::find(names.begin(), names.end(), tech) == names.end()) {
        std::fprintf(stderr, "--variants: '%s' is not <technique>:<parameter>=<value> with a registered technique\n", item.c_str());
        return 2;
      }
      Variant var{tech, item.substr(colon + 1)};
      try {
        render::ParamSet p = render::default_params(*render::create_technique(tech));
        var.apply(p);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "--variants: %s: %s\n", item.c_str(), e.what());
        return 2;
      }
      variants.push_back(var);
    }
    std::stable_sort(variants.begin(), variants.end(), [](const Variant& a, const Variant& b) { return a.technique < b.technique; });
  }
  const int rc = softgi::bench::frame_bench_main(argc, argv, [&](const std::vector<std::string>& backends) {
    for (const auto& scene : scenes)
      for (const auto& b : backends)
        for (const auto& t : variants)
          benchmark::RegisterBenchmark(("BM_Technique/" + scene + "/" + b + "/" + t.label()).c_str(),
                                       [=](benchmark::State& st) { BM_Technique(st, scene, b, t, side); })
              ->Iterations(3)
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond);
  });
  print_table();
  return rc;
}
