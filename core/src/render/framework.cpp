#include <sys/resource.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
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

long long minor_page_faults() {
  rusage u{};
  if (getrusage(RUSAGE_SELF, &u) != 0) return -1;
  return static_cast<long long>(u.ru_minflt);
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

// --- Frame memory -------------------------------------------------------------------------------

std::size_t pixel_count(int width, int height) {
  return static_cast<std::size_t>(std::max(width, 0)) * static_cast<std::size_t>(std::max(height, 0));
}

std::size_t gbuffer_bytes(int width, int height, unsigned planes) {
  // The planes GBuffer::background allocates.
  std::size_t per_pixel = 2 * sizeof(std::int32_t) + sizeof(glm::vec2);
  if (planes & kGBufferSurface) per_pixel += 2 * sizeof(glm::vec3) + sizeof(float);
  if (planes & kGBufferAlbedo) per_pixel += sizeof(glm::vec3);
  if (planes & kGBufferViewDir) per_pixel += sizeof(glm::vec3);
  return pixel_count(width, height) * per_pixel;
}

unsigned frame_gbuffer_planes(const Technique& technique, const ParamSet& params, const std::vector<std::string>& outputs) {
  // A G-buffer requested as an output is handed over whole.
  for (const auto& o : outputs)
    if (o == kGBuffer) return kGBufferAll;
  return technique.gbuffer_planes(params) & kGBufferAll;
}

std::size_t image_bytes(int width, int height) { return pixel_count(width, height) * sizeof(glm::vec3); }

int scaled_size(int size, int scale) { return scale > 0 ? (size + scale - 1) / scale : size; }

std::size_t scene_vertex_count(const scene::Scene& scene) {
  std::size_t n = 0;
  for (const auto& node : scene.nodes)
    if (node.mesh >= 0 && node.mesh < static_cast<int>(scene.meshes.size())) n += scene.meshes[node.mesh].positions.size();
  return n;
}

std::size_t FrameMemory::bytes(MemoryPlace place) const {
  std::size_t persistent = 0;
  std::map<std::string, std::size_t> transient;
  for (const auto& it : items) {
    if (it.place != place) continue;
    if (it.transient) transient[it.pass] += it.bytes;
    else persistent += it.bytes;
  }
  std::size_t peak = 0;
  for (const auto& [pass, b] : transient) peak = std::max(peak, b);
  return persistent + peak;
}

const MemoryItem* FrameMemory::largest(MemoryPlace place) const {
  const MemoryItem* best = nullptr;
  for (const auto& it : items)
    if (it.place == place && (!best || it.bytes > best->bytes)) best = &it;
  return best;
}

std::string format_bytes(std::size_t bytes) {
  const double b = static_cast<double>(bytes);
  char buf[64];
  if (b >= 1024.0 * 1024.0 * 1024.0 * 1024.0) std::snprintf(buf, sizeof buf, "%.1f TiB", b / (1024.0 * 1024.0 * 1024.0 * 1024.0));
  else if (b >= 1024.0 * 1024.0 * 1024.0) std::snprintf(buf, sizeof buf, "%.1f GiB", b / (1024.0 * 1024.0 * 1024.0));
  else if (b >= 1024.0 * 1024.0) std::snprintf(buf, sizeof buf, "%.1f MiB", b / (1024.0 * 1024.0));
  else if (b >= 1024.0) std::snprintf(buf, sizeof buf, "%.1f KiB", b / 1024.0);
  else std::snprintf(buf, sizeof buf, "%zu bytes", bytes);
  return buf;
}

std::size_t parse_memory_size(const std::string& text, const std::string& what) {
  auto fail = [&] {
    return std::invalid_argument(what + ": '" + text + "' is not a memory size (expected e.g. 4GiB, 512M, 1.5GB or 1073741824)");
  };
  std::size_t i = 0;
  while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  const std::size_t start = i;
  while (i < text.size() && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
  if (i == start) throw fail();
  double value = 0.0;
  try {
    std::size_t used = 0;
    value = std::stod(text.substr(start, i - start), &used);
    if (used != i - start) throw fail();
  } catch (const std::invalid_argument&) {
    throw fail();
  } catch (const std::out_of_range&) {
    throw fail();
  }
  while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  std::string unit;
  for (; i < text.size(); ++i) unit += static_cast<char>(std::tolower(static_cast<unsigned char>(text[i])));
  double mult = 1.0;
  if (unit.empty() || unit == "b") mult = 1.0;
  else {
    const char p = unit[0];
    const int power = p == 'k' ? 1 : p == 'm' ? 2 : p == 'g' ? 3 : p == 't' ? 4 : 0;
    const std::string rest = unit.substr(1);
    if (power == 0 || !(rest.empty() || rest == "i" || rest == "ib" || rest == "b")) throw fail();
    mult = std::pow(rest == "b" ? 1000.0 : 1024.0, power);
  }
  const double bytes = value * mult;
  if (!std::isfinite(bytes) || bytes < 1.0 || bytes > 9.0e18) throw fail();
  return static_cast<std::size_t>(bytes);
}

namespace {

// A number from /proc or /sys ("max" and unreadable files: none).
bool read_size_file(const std::string& path, std::size_t& out) {
  std::ifstream f(path);
  std::string v;
  if (!(f >> v) || v == "max") return false;
  try {
    out = static_cast<std::size_t>(std::stoull(v));
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

// `key` of /proc/meminfo or /proc/self/status, in bytes (the files give kB).
bool read_kb_field(const std::string& path, const std::string& key, std::size_t& out) {
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(key, 0) == 0) {
      try {
        out = static_cast<std::size_t>(std::stoull(line.substr(key.size()))) * 1024;
        return true;
      } catch (const std::exception&) {
        return false;
      }
    }
  return false;
}

void take_smaller(MemoryLimits& l, std::size_t bytes, const std::string& source) {
  bytes = std::max<std::size_t>(bytes, 1);  // none left is still a limit (0 would mean none)
  if (l.host == 0 || bytes < l.host) {
    l.host = bytes;
    l.host_source = source;
  }
}

// Limits of the process's memory cgroup and its ancestors: each one's limit less its usage.
void cgroup_limits(MemoryLimits& l) {
  std::ifstream f("/proc/self/cgroup");
  std::string line;
  while (std::getline(f, line)) {
    // v2: "0::/path"; v1: "N:memory:/path" (or with other controllers listed beside memory).
    const std::size_t a = line.find(':'), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1);
    std::string path = line.substr(b + 1);
    const bool v2 = controllers.empty();
    bool v1 = false;
    for (std::size_t p = 0; !v2 && p != std::string::npos;) {
      const std::size_t q = controllers.find(',', p);
      if (controllers.substr(p, q == std::string::npos ? q : q - p) == "memory") v1 = true;
      p = q == std::string::npos ? q : q + 1;
    }
    if (!v2 && !v1) continue;
    const std::string root = v2 ? "/sys/fs/cgroup" : "/sys/fs/cgroup/memory";
    for (;;) {
      const std::string dir = root + (path == "/" ? "" : path);
      std::size_t max = 0, current = 0;
      const bool limited = v2 ? read_size_file(dir + "/memory.max", max) && read_size_file(dir + "/memory.current", current)
                              : read_size_file(dir + "/memory.limit_in_bytes", max) &&
                                    read_size_file(dir + "/memory.usage_in_bytes", current);
      // cgroup v1 reports "no limit" as a huge number (PAGE_COUNTER_MAX pages).
      if (limited && max < (std::size_t{1} << 60))
        take_smaller(l, max > current ? max - current : 0,
                     (v2 ? "memory.max less memory.current of cgroup " : "memory.limit_in_bytes less memory.usage_in_bytes of cgroup ") +
                         path);
      if (path.empty() || path == "/") break;
      const std::size_t slash = path.rfind('/');
      path = slash == 0 || slash == std::string::npos ? "/" : path.substr(0, slash);
    }
  }
}

}  // namespace

MemoryLimits host_memory_limits(std::size_t declared) {
  MemoryLimits l;
  if (declared > 0) {
    l.host = declared;
    l.host_source = "declared limit";
    l.declared = true;
    return l;
  }
  if (const char* env = std::getenv("SOFTGI_MEMORY_LIMIT"); env && *env) {
    std::string v = env;
    std::string lower;
    for (char c : v) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower == "none") {
      l.checked = false;
      return l;
    }
    l.host = parse_memory_size(v, "SOFTGI_MEMORY_LIMIT");
    l.host_source = "SOFTGI_MEMORY_LIMIT=" + v;
    l.declared = true;
    return l;
  }
  std::size_t avail = 0;
  if (read_kb_field("/proc/meminfo", "MemAvailable:", avail)) take_smaller(l, avail, "MemAvailable in /proc/meminfo");
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    std::size_t used = 0;
    read_kb_field("/proc/self/status", "VmSize:", used);
    const std::size_t cap = static_cast<std::size_t>(as.rlim_cur);
    take_smaller(l, cap > used ? cap - used : 0, "RLIMIT_AS less the address space in use");
  }
  cgroup_limits(l);
  return l;
}

void check_frame_memory(const FrameMemory& m, const MemoryLimits& limits, const std::string& device_name) {
  if (!limits.checked) return;
  const std::string frame = "render: " + m.technique + " at " + std::to_string(m.width) + "x" + std::to_string(m.height);
  const std::string who = "the " + m.backend + " backend" + (device_name.empty() ? "" : " (device '" + device_name + "')");
  for (const auto& it : m.items) {
    if (it.place != MemoryPlace::Device) continue;
    if (it.storage_buffer && limits.max_storage_buffer > 0 && it.bytes > limits.max_storage_buffer)
      throw FrameMemoryError(frame + " needs a storage buffer '" + it.name + "' of " + format_bytes(it.bytes) + " (" +
                                 std::to_string(it.bytes) + " bytes); " + who + " allows at most " +
                                 format_bytes(limits.max_storage_buffer) + " per storage buffer (maxStorageBufferRange)",
                             it.name, it.bytes, limits.max_storage_buffer);
    if (limits.max_allocation > 0 && it.bytes > limits.max_allocation)
      throw FrameMemoryError(frame + " needs '" + it.name + "' of " + format_bytes(it.bytes) + " (" + std::to_string(it.bytes) +
                                 " bytes) in one allocation; " + who + " allows at most " + format_bytes(limits.max_allocation) +
                                 " per allocation (maxMemoryAllocationSize)",
                             it.name, it.bytes, limits.max_allocation);
  }
  auto with_margin = [](std::size_t b) { return static_cast<std::size_t>(std::ceil(static_cast<double>(b) * (1.0 + kMemoryMargin))); };
  const int margin_pct = static_cast<int>(std::lround(kMemoryMargin * 100.0));
  auto refuse = [&](const char* kind, std::size_t need, const MemoryItem* big, std::size_t limit, const std::string& source) {
    std::ostringstream os;
    os << frame << " needs about " << format_bytes(need) << " of " << kind << " (largest: '" << (big ? big->name : "?") << "' "
       << format_bytes(big ? big->bytes : 0) << "; the estimate plus " << margin_pct << "%); " << who << " has "
       << format_bytes(limit) << " available (" << source << ")";
    throw FrameMemoryError(os.str(), big ? big->name : "", big ? big->bytes : 0, limit);
  };
  const std::size_t device = m.bytes(MemoryPlace::Device), host = m.bytes(MemoryPlace::Host);
  if (limits.device > 0 && device > 0 && with_margin(device) > limits.device)
    refuse("device memory", with_margin(device), m.largest(MemoryPlace::Device), limits.device, limits.device_source);
  if (limits.host > 0) {
    const std::size_t need = with_margin(host + (limits.device_is_host_memory ? device : 0));
    if (need > limits.host) {
      const MemoryItem* big = m.largest(MemoryPlace::Host);
      const MemoryItem* dbig = limits.device_is_host_memory ? m.largest(MemoryPlace::Device) : nullptr;
      if (dbig && (!big || dbig->bytes > big->bytes)) big = dbig;
      refuse(limits.device_is_host_memory ? "memory (host and device)" : "host memory", need, big, limits.host, limits.host_source);
    }
  }
}

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
  std::set<std::string> empty;
  PassGraph graph = technique.plan(scene, params, empty);
  CompiledGraph compiled = graph.compile(request.outputs, empty);
  // Before anything large is allocated (the posed scene included). The pool's buffers count as used
  // memory in the limits; when the frame does not fit beside them, they are freed and it is asked
  // again.
  const FrameMemory need =
      estimate_compiled(technique, scene, params, graph, compiled, w, h, frame_gbuffer_planes(technique, params, request.outputs));
  try {
    check_frame_memory(need, memory_limits(), memory_device_name());
  } catch (const FrameMemoryError&) {
    if (pool_.stats().held_bytes == 0) throw;
    pool_.clear();
    check_frame_memory(need, memory_limits(), memory_device_name());
  }
  scene::PosedScene posed = scene::evaluate(scene, request.time);
  result.pruned = compiled.pruned;
  result.warnings = compiled.warnings;
  FrameContext ctx(scene, posed, params, w, h, result, device(), &pool_);
  ctx.set_gbuffer_planes(frame_gbuffer_planes(technique, params, request.outputs));
  for (int i : compiled.order) {
    const PassDesc& pass = graph.passes()[i];
    result.passes.push_back(PassRecord{pass.name});
    auto p0 = std::chrono::steady_clock::now();
    const TransferBytes before = transfer_total();
    const long long faults0 = minor_page_faults();
    execute_pass(pass, ctx);
    const long long faults1 = minor_page_faults();
    if (faults0 >= 0 && faults1 >= 0) result.passes.back().page_faults = faults1 - faults0;
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
  ctx.release_to_pool();
  pool_.end_frame();
  result.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.peak_rss_bytes = peak_rss_bytes();
  return result;
}

void Backend::recycle(FrameResult&& frame) {
  pool_.give(std::move(frame.direct));
  pool_.give(std::move(frame.indirect));
  pool_.give(std::move(frame.final_image));
  for (auto& v : frame.vertex_radiance) pool_.give(std::move(v));
  for (auto& [name, value] : frame.resources) pool_.give_any(value);
  frame = FrameResult();
}

FrameMemory Backend::estimate_compiled(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                                       const PassGraph& graph, const CompiledGraph& compiled, int w, int h,
                                       unsigned gbuffer_planes) {
  FrameMemory m;
  m.technique = technique.name();
  m.backend = name();
  m.width = w;
  m.height = h;
  std::vector<const PassDesc*> order;
  std::map<std::string, const PassDesc*> runs;
  for (int i : compiled.order) {
    order.push_back(&graph.passes()[i]);
    runs[graph.passes()[i].name] = &graph.passes()[i];
  }
  // The posed scene: world-space positions and normals of every vertex (scene::evaluate).
  m.items.push_back({"posed scene", scene_vertex_count(scene) * 2 * sizeof(glm::vec3), MemoryPlace::Host, "", false, false});
  // The shared passes' resources, whatever implementation runs them.
  if (runs.count("gbuffer"))
    m.items.push_back({kGBuffer, gbuffer_bytes(w, h, gbuffer_planes), MemoryPlace::Host, "gbuffer", false, false});
  if (runs.count("receiver_gbuffer")) {
    const int s = params.has("receiver_scale") ? params.get_int("receiver_scale") : 1;
    m.items.push_back({kReceiverGBuffer, gbuffer_bytes(scaled_size(w, s), scaled_size(h, s)), MemoryPlace::Host, "receiver_gbuffer",
                       false, false});
  }
  if (runs.count("compose")) m.items.push_back({kFinal, image_bytes(w, h), MemoryPlace::Host, "compose", false, false});
  const bool has_device = device() != nullptr;
  for (MemoryItem& it : technique.estimate_memory(scene, params, w, h)) {
    if (!it.pass.empty()) {
      auto p = runs.find(it.pass);
      if (p == runs.end()) continue;
      // A device item is the backend's kernels' allocation: not made where the host code runs the pass.
      const bool own = has_device && (p->second->impl.count(name()) || find_shared_pass_impl(it.pass, name()));
      if (it.place == MemoryPlace::Device ? !own : (it.host_only && own)) continue;
    } else if (it.place == MemoryPlace::Device && !has_device) {
      continue;
    }
    m.items.push_back(std::move(it));
  }
  add_backend_memory(order, scene, params, w, h, m.items);
  return m;
}

FrameMemory Backend::estimate_memory(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                                     const RenderRequest& request) {
  const int w = request.width > 0 ? request.width : scene.camera.width;
  const int h = request.height > 0 ? request.height : scene.camera.height;
  std::set<std::string> empty;
  PassGraph graph = technique.plan(scene, params, empty);
  const CompiledGraph compiled = graph.compile(request.outputs, empty);
  return estimate_compiled(technique, scene, params, graph, compiled, w, h,
                           frame_gbuffer_planes(technique, params, request.outputs));
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
