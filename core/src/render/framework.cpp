#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
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
  const TransferBytes moved0 = transfer_total();
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
  result.warnings = compiled.warnings;
  FrameContext ctx(scene, posed, params, w, h, result, device());
  for (int i : compiled.order) {
    const PassDesc& pass = graph.passes()[i];
    result.passes.push_back(PassRecord{pass.name});
    auto p0 = std::chrono::steady_clock::now();
    const TransferBytes before = transfer_total();
    execute_pass(pass, ctx);
    const TransferBytes after = transfer_total();
    result.passes.back().transfer = {after.upload - before.upload, after.download - before.download};
    result.passes.back().wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - p0).count();
  }
  // The frame's output images, unless a pass filled the result itself.
  for (auto [resource, field] : {std::pair<const char*, Image*>{kDirect, &result.direct},
                                 {kIndirect, &result.indirect}, {kFinal, &result.final_image}})
    if (field->empty() && ctx.has(resource)) *field = std::move(ctx.get<Image>(resource));
  for (const auto& o : request.outputs)
    if (o != kDirect && o != kIndirect && o != kFinal && ctx.has(o)) result.resources[o] = ctx.get_any(o);
  const TransferBytes moved1 = transfer_total();
  result.transfer = {moved1.upload - moved0.upload, moved1.download - moved0.download};
  result.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.peak_rss_bytes = peak_rss_bytes();
  return result;
}

const PassFn* find_pass_impl(const PassDesc& pass, const std::string& backend) {
  auto it = pass.impl.find(backend);
  if (it != pass.impl.end()) return &it->second;
  if (backend != kHostImpl)
    if (const PassFn* shared = find_shared_pass_impl(pass.name, backend)) return shared;
  it = pass.impl.find(kHostImpl);
  return it == pass.impl.end() ? nullptr : &it->second;
}

void Backend::execute_pass(const PassDesc& pass, FrameContext& ctx) {
  // The backend's own implementation, then the backend's implementation of a shared pass, then the
  // host code every backend can run.
  const PassFn* fn = find_pass_impl(pass, name());
  if (!fn) throw std::logic_error("pass '" + pass.name + "' has no implementation for the " + name() + " backend");
  (*fn)(ctx);
}

SteppedFrame::SteppedFrame(Technique& technique, const scene::Scene& scene, const ParamSet& params, const RenderRequest& request,
                           Device* device) {
  result_.technique = technique.name();
  const int w = request.width > 0 ? request.width : scene.camera.width;
  const int h = request.height > 0 ? request.height : scene.camera.height;
  posed_ = scene::evaluate(scene, request.time);
  std::set<std::string> empty;
  graph_ = technique.plan(scene, params, empty);
  const CompiledGraph compiled = graph_.compile(request.outputs, empty);
  result_.pruned = compiled.pruned;
  result_.warnings = compiled.warnings;
  for (int i : compiled.order) order_.push_back(&graph_.passes()[i]);
  ctx_ = std::make_unique<FrameContext>(scene, posed_, params, w, h, result_, device);
}

const PassDesc& SteppedFrame::pass(const std::string& name) const {
  for (const PassDesc* p : order_)
    if (p->name == name) return *p;
  throw std::invalid_argument("stepped frame: no pass '" + name + "' runs in this frame");
}

void SteppedFrame::run(const PassDesc& pass, const std::string& backend, const std::string& label) {
  const PassFn* fn = find_pass_impl(pass, backend);
  if (!fn) throw std::logic_error("pass '" + pass.name + "' has no implementation for " + backend);
  result_.passes.push_back(PassRecord{label.empty() ? pass.name : label});
  const auto t0 = std::chrono::steady_clock::now();
  (*fn)(*ctx_);
  result_.passes.back().wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void NullBackend::execute_pass(const PassDesc& pass, FrameContext&) { executed.push_back(pass.name); }

// --- The backend registry ---------------------------------------------------------------------

namespace {
std::mutex& backend_mutex() {
  static std::mutex m;
  return m;
}
std::vector<BackendInfo>& backend_registry() {
  static std::vector<BackendInfo> r;
  return r;
}
std::string known_backends() {
  std::string known;
  for (const auto& b : backend_registry()) known += (known.empty() ? "" : ", ") + b.name;
  return known.empty() ? "none" : known;
}
}  // namespace

void register_backend(BackendInfo info) {
  std::lock_guard<std::mutex> lock(backend_mutex());
  if (info.name.empty() || info.name == kHostImpl)
    throw std::logic_error("register_backend: invalid backend name '" + info.name + "'");
  if (!info.create) throw std::logic_error("register_backend: backend '" + info.name + "' has no factory");
  for (const auto& b : backend_registry())
    if (b.name == info.name) throw std::logic_error("backend '" + info.name + "' registered twice");
  backend_registry().push_back(std::move(info));
}

std::vector<std::string> backend_names() {
  std::lock_guard<std::mutex> lock(backend_mutex());
  std::vector<std::string> names;
  for (const auto& b : backend_registry()) names.push_back(b.name);
  return names;
}

const BackendInfo& backend_info(const std::string& name) {
  std::lock_guard<std::mutex> lock(backend_mutex());
  for (const auto& b : backend_registry())
    if (b.name == name) return b;  // entries are never removed: the reference stays valid
  throw std::invalid_argument("unknown backend '" + name + "' (available: " + known_backends() + ")");
}

std::string reference_backend_name() {
  std::lock_guard<std::mutex> lock(backend_mutex());
  if (backend_registry().empty()) throw std::logic_error("no backend is registered");
  return backend_registry().front().name;
}

std::unique_ptr<Backend> create_backend(const std::string& name, const BackendOptions& options) {
  const BackendInfo& info = backend_info(name);
  if (!options.device.empty() && !info.selects_device)
    throw std::invalid_argument("--device '" + options.device + "': the " + name + " backend selects no device");
  if (info.unavailable) {
    const std::string why = info.unavailable();
    if (!why.empty()) throw std::invalid_argument("backend '" + name + "' is unavailable here: " + why);
  }
  return info.create(options);
}

// --- Rendering ----------------------------------------------------------------------------------

FrameResult render_frame(Backend& backend, const std::string& technique, const scene::Scene& scene, const ParamSet* params,
                         const RenderRequest& request) {
  std::unique_ptr<Technique> t = create_technique(technique);
  const ParamSet defaults = default_params(*t);
  return backend.render(*t, scene, params ? *params : defaults, request);
}

namespace {
// The shared G-buffer pass and a host pass that hands its result out of the frame.
class GBufferOnly final : public Technique {
 public:
  explicit GBufferOnly(GBuffer* out) : out_(out) {}
  std::string name() const override { return "gbuffer"; }
  std::string description() const override { return "the shared display G-buffer"; }
  std::vector<ParamDesc> params() const override { return {}; }
  PassGraph plan(const scene::Scene&, const ParamSet&, std::set<std::string>&) override {
    PassGraph g;
    add_gbuffer_pass(g);
    GBuffer* out = out_;
    g.add({"gbuffer_output", {kGBuffer}, {}, {"gbuffer_output"}, "the G-buffer handed to the caller",
           host_impl([out](FrameContext& c) { *out = std::move(c.get<GBuffer>(kGBuffer)); })});
    return g;
  }

 private:
  GBuffer* out_;
};
}  // namespace

GBufferFrame render_gbuffer(Backend& backend, const scene::Scene& scene, const RenderRequest& request) {
  GBufferFrame f;
  GBufferOnly t(&f.gbuffer);
  RenderRequest r = request;
  r.outputs = {"gbuffer_output"};
  f.frame = backend.render(t, scene, ParamSet(), r);
  return f;
}

}  // namespace softgi::render
