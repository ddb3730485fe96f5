#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"

namespace softgi::render {

std::size_t FrameResult::bytes() const {
  std::size_t b = 0;
  for (const auto& p : passes) b += p.bytes;
  return b;
}

std::size_t peak_rss_bytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return static_cast<std::size_t>(std::stoull(line.substr(6))) * 1024;
  return 0;
}

namespace {
std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, TechniqueFactory>& registry() {
  static std::map<std::string, TechniqueFactory> r;
  return r;
}
}  // namespace

void register_technique(const std::string& name, TechniqueFactory factory) {
  std::lock_guard<std::mutex> lock(registry_mutex());
  if (registry().count(name)) throw std::logic_error("technique '" + name + "' registered twice");
  registry()[name] = std::move(factory);
}

std::vector<std::string> technique_names() {
  std::lock_guard<std::mutex> lock(registry_mutex());
  std::vector<std::string> names;
  for (const auto& [n, f] : registry()) names.push_back(n);
  return names;
}

std::unique_ptr<Technique> create_technique(const std::string& name) {
  TechniqueFactory f;
  {
    std::lock_guard<std::mutex> lock(registry_mutex());
    auto it = registry().find(name);
    if (it != registry().end()) f = it->second;
  }
  if (!f) {
    std::string known;
    for (const auto& n : technique_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown technique '" + name + "' (known: " + (known.empty() ? "none" : known) + ")");
  }
  return f();
}

ParamSet default_params(const Technique& t) { return ParamSet(t.params()); }

FrameResult Backend::render(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                            const RenderRequest& request) {
  auto t0 = std::chrono::steady_clock::now();
  FrameResult result;
  result.technique = technique.name();
  result.backend = name();
  const int w = request.width > 0 ? request.width : scene.camera.width;
  const int h = request.height > 0 ? request.height : scene.camera.height;
  if (w < 1 || h < 1 || w > 16384 || h > 16384)
    throw std::invalid_argument("render: resolution " + std::to_string(w) + "x" + std::to_string(h) + " outside 1..16384");
  scene::PosedScene posed = scene::evaluate(scene, request.time);
  std::set<std::string> empty;
  PassGraph graph = technique.plan(scene, params, empty);
  CompiledGraph compiled = graph.compile(request.outputs, empty);
  result.pruned = compiled.pruned;
  FrameContext ctx(scene, posed, params, w, h, result);
  for (int i : compiled.order) {
    const PassDesc& pass = graph.passes()[i];
    result.passes.push_back(PassRecord{pass.name});
    auto p0 = std::chrono::steady_clock::now();
    execute_pass(pass, ctx);
    result.passes.back().wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - p0).count();
  }
  // The frame's output images, unless a pass filled the result itself.
  for (auto [resource, field] : {std::pair<const char*, Image*>{kDirect, &result.direct},
                                 {kIndirect, &result.indirect}, {kFinal, &result.final_image}})
    if (field->empty() && ctx.has(resource)) *field = std::move(ctx.get<Image>(resource));
  result.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.peak_rss_bytes = peak_rss_bytes();
  return result;
}

void Backend::execute_pass(const PassDesc& pass, FrameContext& ctx) {
  auto it = pass.impl.find(name());
  if (it != pass.impl.end()) {
    it->second(ctx);
    return;
  }
  if (const PassFn* shared = find_shared_pass_impl(pass.name, name())) {
    (*shared)(ctx);
    return;
  }
  throw std::logic_error("pass '" + pass.name + "' has no implementation for the " + name() + " backend");
}

void NullBackend::execute_pass(const PassDesc& pass, FrameContext&) { executed.push_back(pass.name); }

}  // namespace softgi::render
