// Backends execute compiled pass graphs; the backend registry lists those a build has. The render
// calls here are the library API: every command, benchmark and test renders through them.
#pragma once

#include <functional>
#include <map>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"

namespace softgi::render {

// --- Frame memory -------------------------------------------------------------------------------

// What a backend may still allocate (Backend::memory_limits). 0 means no limit of that kind.
struct MemoryLimits {
  std::size_t host = 0;  // process memory still available
  std::string host_source;  // where `host` comes from ("MemAvailable in /proc/meminfo", "SOFTGI_MEMORY_LIMIT", ...)
  std::size_t device = 0;  // device memory (a device backend's largest device-local heap)
  std::string device_source;
  std::size_t max_storage_buffer = 0;  // one storage buffer (Vulkan: maxStorageBufferRange)
  std::size_t max_allocation = 0;      // one allocation (Vulkan: maxMemoryAllocationSize)
  // Device memory is process memory (a CPU device such as lavapipe): device items count against
  // `host` as well.
  bool device_is_host_memory = false;
  bool checked = true;    // false: SOFTGI_MEMORY_LIMIT=none, nothing is refused
  bool declared = false;  // `host` is a declared limit (Backend::set_memory_limit, SOFTGI_MEMORY_LIMIT)
};

// A frame's large resources on one backend (Backend::estimate_memory): the technique's, the shared
// passes' and the backend's own, for the passes the compiled graph runs.
struct FrameMemory {
  std::string technique, backend;
  int width = 0, height = 0;
  std::vector<MemoryItem> items;
  // The persistent items of `place` plus the transient ones of the pass that has the most.
  std::size_t bytes(MemoryPlace place) const;
  // The largest item of `place` (null when there is none).
  const MemoryItem* largest(MemoryPlace place) const;
};

// Totals are compared with a limit after adding this fraction, for what the estimate leaves out
// (tables, the BVH, thread arenas, proxy bins, allocator rounding): at 2048x2048 the listed
// resources are 0.96 of a shexp frame's measured growth of the resident set (docs/backends.md,
// "Memory limits"). Per-buffer and per-allocation limits are compared with exact sizes.
inline constexpr double kMemoryMargin = 0.10;

// A frame that does not fit: names the resource (the largest of the total that is too large, or
// the one buffer over a per-buffer limit), its size and the limit.
class FrameMemoryError : public std::runtime_error {
 public:
  FrameMemoryError(const std::string& what, std::string resource, std::size_t bytes, std::size_t limit)
      : std::runtime_error(what), resource_(std::move(resource)), bytes_(bytes), limit_(limit) {}
  const std::string& resource() const { return resource_; }
  std::size_t bytes() const { return bytes_; }  // of the resource
  std::size_t limit() const { return limit_; }

 private:
  std::string resource_;
  std::size_t bytes_, limit_;
};

// Throws FrameMemoryError when `m` does not fit `limits`, checking in this order: a device item
// over max_storage_buffer (storage buffers) or max_allocation, the device total (with the margin)
// over `device`, the host total (plus the device total where device memory is host memory, with
// the margin) over `host`. `device_name` names the device in the messages ("" = the backend).
void check_frame_memory(const FrameMemory& m, const MemoryLimits& limits, const std::string& device_name = "");

// The process memory still available: the smallest of MemAvailable (/proc/meminfo), RLIMIT_AS less
// the address space in use, and memory.max less memory.current of the process's cgroup and its
// ancestors (cgroup v2; v1: memory.limit_in_bytes less memory.usage_in_bytes). A declared limit
// replaces them: `declared` when non-zero, else the environment variable SOFTGI_MEMORY_LIMIT (a size
// such as 4GiB, 512M or 1073741824; "none" switches the check off). Throws std::invalid_argument
// for a SOFTGI_MEMORY_LIMIT that is not a size.
MemoryLimits host_memory_limits(std::size_t declared = 0);
// "4GiB", "4G", "512 MiB", "1.5GB", "65536", "64k" (K/M/G/T and KiB/MiB/GiB/TiB are powers of 1024;
// KB/MB/GB/TB powers of 1000): bytes. Throws std::invalid_argument naming `what` and the text.
std::size_t parse_memory_size(const std::string& text, const std::string& what);
// "54.2 GiB", "310.0 MiB", "512 bytes".
std::string format_bytes(std::size_t bytes);

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // The device passes run on (FrameContext::device); null for the host-only CPU backend.
  virtual Device* device() { return nullptr; }
  // For run records: what the device is (name, type, driver, ...); empty for the CPU backend.
  virtual std::map<std::string, std::string> device_record() const { return {}; }
  // Poses the scene at request.time, plans, compiles for request.outputs, executes and times every
  // pass, and records each pass's host <-> device transfers. A needed pass without an implementation
  // for this backend is an error naming both.
  // Before the first pass, the frame's memory (estimate_memory) is checked against memory_limits():
  // a frame that does not fit is a FrameMemoryError naming the resource, its size and the limit.
  virtual FrameResult render(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                             const RenderRequest& request);
  // Hands a frame back when the caller is done with it: its images and buffers go to the backend's
  // FramePool, where the next frame's passes take them instead of allocating (and page-faulting)
  // new ones. A caller rendering a sequence calls it once per frame; not calling it only costs time.
  void recycle(FrameResult&& frame);
  // The pool render() takes frames' buffers from and leaves them in (FramePool).
  FramePool& frame_pool() { return pool_; }
  // The frame's large resources on this backend, planned and compiled as render() would; runs no pass.
  FrameMemory estimate_memory(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                              const RenderRequest& request);
  // What this backend may allocate now: host_memory_limits(declared limit), and a device backend's
  // device limits.
  virtual MemoryLimits memory_limits() const { return host_memory_limits(memory_limit_); }
  // A declared limit (bytes) that replaces the machine's process and device memory totals in the
  // check (tests, BackendOptions::memory_limit); 0: the machine's (or SOFTGI_MEMORY_LIMIT).
  void set_memory_limit(std::size_t bytes) { memory_limit_ = bytes; }
  std::size_t memory_limit() const { return memory_limit_; }

 protected:
  virtual void execute_pass(const PassDesc& pass, FrameContext& ctx);
  // The backend's own allocations for the frame's passes (`passes`, in order) beyond the
  // technique's items: a device backend's targets and buffers for the shared passes.
  virtual void add_backend_memory(const std::vector<const PassDesc*>& passes, const scene::Scene& scene, const ParamSet& params,
                                  int width, int height, std::vector<MemoryItem>& items) const {
    (void)passes, (void)scene, (void)params, (void)width, (void)height, (void)items;
  }
  // The device name in memory errors ("" = none).
  virtual std::string memory_device_name() const { return {}; }
  // Host <-> device bytes moved since the backend was created (zero without a device).
  virtual TransferBytes transfer_total() const { return {}; }

 private:
  FrameMemory estimate_compiled(Technique& technique, const scene::Scene& scene, const ParamSet& params, const PassGraph& graph,
                                const CompiledGraph& compiled, int width, int height, unsigned gbuffer_planes);
  std::size_t memory_limit_ = 0;
  FramePool pool_;
};

// Runs no pass implementation; records which passes would run (for graph tests).
class NullBackend : public Backend {
 public:
  std::string name() const override { return "null"; }
  std::vector<std::string> executed;

 protected:
  void execute_pass(const PassDesc& pass, FrameContext& ctx) override;
};

// What `backend` runs for `pass`: its own implementation, else its implementation of a shared pass,
// else the host implementation (kHostImpl names the host one alone); null when there is none.
const PassFn* find_pass_impl(const PassDesc& pass, const std::string& backend);

// A frame run pass by pass by the caller: posed, planned and compiled as Backend::render does, so
// that a test can run one pass on two backends from the same inputs (backend parity) or stop after
// a pass. run() records each pass in result() as Backend::render would. The scene and the
// parameters must outlive the frame.
class SteppedFrame {
 public:
  SteppedFrame(Technique& technique, const scene::Scene& scene, const ParamSet& params, const RenderRequest& request,
               Device* device = nullptr);
  SteppedFrame(const SteppedFrame&) = delete;
  SteppedFrame& operator=(const SteppedFrame&) = delete;
  // The passes to run, in dependency order.
  const std::vector<const PassDesc*>& passes() const { return order_; }
  const PassDesc& pass(const std::string& name) const;  // throws std::invalid_argument naming it
  FrameContext& context() { return *ctx_; }
  FrameResult& result() { return result_; }
  // Runs `pass` as `backend` would (find_pass_impl), recorded as `label` (default: the pass name).
  // Throws std::logic_error when the backend has no implementation of it.
  void run(const PassDesc& pass, const std::string& backend, const std::string& label = "");

 private:
  FrameResult result_;
  scene::PosedScene posed_;
  PassGraph graph_;
  std::vector<const PassDesc*> order_;
  std::unique_ptr<FrameContext> ctx_;
};

// --- The backend registry ---------------------------------------------------------------------

struct BackendOptions {
  std::string device;   // a device by name or index, for backends that select one ("" = the best)
  int validation = -1;  // API validation layers: 1 on, 0 off, -1 the backend's default
  std::size_t memory_limit = 0;  // Backend::set_memory_limit (0: the machine's, or SOFTGI_MEMORY_LIMIT)
};

struct BackendInfo {
  std::string name, description;
  bool selects_device = false;  // BackendOptions::device means something
  // "" when the backend can run on this machine, else why it cannot (no driver, no device, ...).
  std::function<std::string()> unavailable;
  std::function<std::unique_ptr<Backend>(const BackendOptions&)> create;
};

// Throws std::logic_error when the name is taken. The first registered backend is the reference
// the others are compared with.
void register_backend(BackendInfo info);
std::vector<std::string> backend_names();  // registration order
// Throws std::invalid_argument naming the unknown backend and the registered ones.
const BackendInfo& backend_info(const std::string& name);
// The reference backend's name (the first registered); throws std::logic_error when none is.
std::string reference_backend_name();
// Throws std::invalid_argument for an unknown backend, for a device option the backend does not
// take, and for an unavailable backend (with the reason).
std::unique_ptr<Backend> create_backend(const std::string& name, const BackendOptions& options = {});

// --- Rendering ----------------------------------------------------------------------------------

// One frame of the registered technique `technique` with `params` (defaults where null), on a
// technique object made for it: no state carries over from an earlier call (a caller rendering a
// sequence keeps one Technique and calls Backend::render, so that tables and hierarchies are built
// once).
FrameResult render_frame(Backend& backend, const std::string& technique, const scene::Scene& scene,
                         const ParamSet* params, const RenderRequest& request);

// The display G-buffer alone (the shared "gbuffer" pass), as a frame of its own: what compare and
// experiments measure errors over.
struct GBufferFrame {
  GBuffer gbuffer;
  FrameResult frame;
};
GBufferFrame render_gbuffer(Backend& backend, const scene::Scene& scene, const RenderRequest& request);

}  // namespace softgi::render
