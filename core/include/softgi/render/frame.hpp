// What a frame produces, and the context passes run in.
#pragma once

#include <any>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/render/frame_pool.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/pass_graph.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::render {

// Bytes moved between host memory and a backend's device memory (zero on the CPU backend).
struct TransferBytes {
  std::size_t upload = 0, download = 0;
  TransferBytes& operator+=(const TransferBytes& o) {
    upload += o.upload;
    download += o.download;
    return *this;
  }
};

struct PassRecord {
  std::string name;
  double wall_seconds = 0.0;
  double gpu_seconds = -1.0;                 // GPU timestamps where the backend has them
  std::map<std::string, double> counters;    // receivers, blockers accumulated, ...
  std::size_t bytes = 0;                     // tables and buffers this pass allocated or holds
  TransferBytes transfer;                    // host <-> device bytes this pass moved
  // Minor page faults of the whole process while the pass ran (first touches of fresh memory; -1
  // where the platform does not count them). Every one is a trip into the kernel, which on some
  // machines costs more than the pass's own work (bench/README.md, "Frame memory").
  long long page_faults = -1;
};

struct FrameResult {
  std::string technique, backend;
  Image direct, indirect, final_image;  // display resolution, outgoing radiance (linear HDR)
  // Per-vertex outgoing radiance per posed object, where a technique shades vertices.
  std::vector<std::vector<glm::vec3>> vertex_radiance;
  std::vector<PassRecord> passes;       // executed passes, in order
  std::vector<PrunedPass> pruned;       // left-out passes and why
  double total_seconds = 0.0;
  std::size_t peak_rss_bytes = 0;       // process peak resident memory after the frame
  // Requested outputs other than the three images (RenderRequest::outputs may name any resource of
  // the technique's graph, e.g. an intermediate for a parity test), as the graph's passes hold them.
  std::map<std::string, std::any> resources;
  // Host <-> device bytes of the frame: the passes' plus what the backend moved outside any pass
  // (requested outputs read back after the last pass).
  TransferBytes transfer;
  // What the frame could not do as asked, one sentence each (shadows left out for want of proxies,
  // receivers too coarse for the proxies that shade them): the CLI prints them and records keep them.
  std::vector<std::string> warnings;
  std::size_t bytes() const;            // sum over passes
};

struct RenderRequest {
  double time = 0.0;
  int width = 0, height = 0;  // 0: the scene camera's
  std::vector<std::string> outputs = {"final"};
};

// The device a backend runs its passes on (the Vulkan backend's vulkan::Context). A pass's
// backend-specific implementation gets it from FrameContext::device and casts it to its own type;
// host passes never touch it. Null on the CPU backend.
class Device {
 public:
  virtual ~Device() = default;
  virtual std::string backend_name() const = 0;
};

// Typed blackboard of a frame's resources plus what passes report.
class FrameContext {
 public:
  // `pool`: the executing backend's FramePool, where passes take their large buffers and where
  // release_to_pool() leaves them; null: a pool of the frame's own (nothing carries over).
  FrameContext(const scene::Scene& scene, const scene::PosedScene& posed, const ParamSet& params, int width,
               int height, FrameResult& result, Device* device = nullptr, FramePool* pool = nullptr)
      : scene(scene), posed(posed), params(params), width(width), height(height), result(result), device(device),
        pool_(pool ? pool : &own_pool_) {}
  // Deferred resources refer to their frame: a frame is neither copied nor moved.
  FrameContext(const FrameContext&) = delete;
  FrameContext& operator=(const FrameContext&) = delete;

  const scene::Scene& scene;
  const scene::PosedScene& posed;
  const ParamSet& params;
  const int width, height;
  FrameResult& result;
  Device* const device;  // the executing backend's device; null for host-only backends

  template <class T>
  T& put(const std::string& name, T value) {
    deferred_.erase(name);
    device_.erase(name);  // a host value replaces whatever a device pass left
    resources_[name] = std::move(value);
    return std::any_cast<T&>(resources_[name]);
  }
  // A resource whose host copy is made only when a pass (or the caller) first asks for it with
  // get(): a device backend's pass leaves its result in device memory and says how to read it back,
  // so that the next device pass reads it there and nothing crosses the bus unless a host pass
  // needs it. is_deferred() tells the two apart without reading back.
  template <class T>
  void put_deferred(const std::string& name, std::function<T()> make) {
    resources_.erase(name);
    deferred_[name] = [this, name, make = std::move(make)]() { resources_[name] = make(); };
  }
  bool is_deferred(const std::string& name) const { return deferred_.count(name) != 0; }
  // The device copy of a resource (a backend's buffer handle type D), kept beside its host value or
  // deferred read-back until a host put() replaces the resource; null when there is none.
  template <class D>
  void put_device(const std::string& name, D copy) {
    device_[name] = std::move(copy);
  }
  template <class D>
  const D* device_copy(const std::string& name) const {
    auto it = device_.find(name);
    return it == device_.end() ? nullptr : std::any_cast<D>(&it->second);
  }
  template <class T>
  T& get(const std::string& name) {
    T* p = std::any_cast<T>(&get_any(name));
    if (!p) throw std::logic_error("frame resource '" + name + "' has another type");
    return *p;
  }
  // The resource whatever its type (a deferred one is read back first).
  std::any& get_any(const std::string& name) {
    auto it = resources_.find(name);
    if (it == resources_.end()) {
      auto d = deferred_.find(name);
      if (d == deferred_.end()) throw std::logic_error("frame resource '" + name + "' was never produced");
      std::function<void()> make = std::move(d->second);
      deferred_.erase(d);
      make();
      it = resources_.find(name);
    }
    return it->second;
  }
  bool has(const std::string& name) const { return resources_.count(name) != 0 || deferred_.count(name) != 0; }
  // Where passes take display-resolution buffers (FramePool::image_for_overwrite, take): last
  // frame's, when the backend keeps a pool.
  FramePool& pool() { return *pool_; }
  // Gives every host resource of a type the pool knows to the pool (after the frame's outputs have
  // been moved out) and forgets the deferred ones.
  void release_to_pool() {
    for (auto& [name, value] : resources_) pool_->give_any(value);
    resources_.clear();
    deferred_.clear();
    for (auto& fn : on_release_) fn(*pool_);
    on_release_.clear();
  }
  // Runs `fn` with the pool in release_to_pool, after the resources are released: for a pass's own
  // structure that the pool does not know, whose buffers `fn` gives back when nothing else holds it
  // (a shared_ptr the lambda keeps, with use_count() 1).
  void on_release(std::function<void(FramePool&)> fn) { on_release_.push_back(std::move(fn)); }
  // The record of the pass being executed (counters, bytes).
  PassRecord& record() { return result.passes.back(); }
  // The planes the frame's G-buffer holds (GBufferPlanes): what the technique's passes read
  // (Technique::gbuffer_planes), all of them when the G-buffer is a requested output.
  unsigned gbuffer_planes() const { return gbuffer_planes_; }
  // Unique among the frames of the process (never 0): lets a backend keep work for the rest of one
  // frame (the CPU rasteriser's set-up, shared by the display and receiver G-buffers) without
  // mistaking a later frame for it, whatever address that frame's objects have.
  std::uint64_t id() const { return id_; }
  void set_gbuffer_planes(unsigned planes) { gbuffer_planes_ = planes; }
  // Adds a frame warning (FrameResult::warnings) once, however many passes report it.
  void warn(const std::string& message) {
    for (const auto& w : result.warnings)
      if (w == message) return;
    result.warnings.push_back(message);
  }

 private:
  std::map<std::string, std::any> resources_;
  std::map<std::string, std::function<void()>> deferred_;
  std::map<std::string, std::any> device_;
  std::vector<std::function<void(FramePool&)>> on_release_;
  FramePool own_pool_;
  FramePool* pool_;
  unsigned gbuffer_planes_ = kGBufferAll;
  const std::uint64_t id_ = next_id();
  static std::uint64_t next_id() {
    static std::atomic<std::uint64_t> n{0};
    return ++n;
  }
};

// Peak resident set size of this process (VmHWM), 0 where unavailable.
std::size_t peak_rss_bytes();
// Minor page faults of this process so far (getrusage), -1 where unavailable.
long long minor_page_faults();

}  // namespace softgi::render
