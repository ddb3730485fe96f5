// softgi's Vulkan infrastructure (softgi::vulkan): instance and device, validation, buffers and
// images, SPIR-V-reflected pipeline layouts, compute pipelines, one-shot submissions with GPU
// timestamps. Every object is RAII; a Context destroys everything it made before its device.
//
// This header includes <vulkan/vulkan.h>: include it only from translation units that record
// Vulkan work (backends/vulkan/*.cpp, techniques/*/*_vulkan.cpp, tests/vulkan). The backend class
// the application sees (vulkan_backend.hpp) does not include it.
//
// Shaders: GLSL in shaders/, compiled at build time by softgi_add_shaders() (cmake/SoftgiShaders.cmake)
// into generated headers <softgi/shaders/NAME_STAGE.h> holding `const uint32_t NAME_STAGE[]`; constants
// shared by C++ and GLSL live in shaders/include/softgi_shared.h. Descriptor set layouts and push
// constant ranges are never written by hand: they come from reflect_spirv() of the shader words.
#pragma once

#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "softgi/render/frame.hpp"

namespace softgi::render {
class FrameContext;
}

namespace softgi::backends::vulkan {

// A failed Vulkan call: names the call (or the submission) and the VkResult.
class VulkanError : public std::runtime_error {
 public:
  VulkanError(const std::string& what, VkResult result);
  VkResult result() const { return result_; }

 private:
  VkResult result_;
};
const char* to_string(VkResult r);
// Throws VulkanError("<what>: VK_ERROR_...") unless r == VK_SUCCESS.
void check(VkResult r, const char* what);

// ---------------------------------------------------------------------------------------------
// Validation messages (VK_LAYER_KHRONOS_validation through VK_EXT_debug_utils). Shared with the
// Context so that what the layer reports while the device and instance are destroyed (leaked
// objects) can still be read after the Context is gone.
struct ValidationMessage {
  enum class Severity { Verbose, Info, Warning, Error };
  Severity severity = Severity::Info;
  std::string id;    // message id name (a VUID for validation errors)
  std::string text;
};

class ValidationLog {
 public:
  void add(ValidationMessage m);  // thread-safe
  std::size_t errors() const;
  std::size_t warnings() const;
  std::size_t problems() const { return errors() + warnings(); }  // what tests require to be 0
  std::vector<ValidationMessage> messages() const;                 // warnings and errors
  std::string summary(std::size_t max_messages = 8) const;         // for test failure output
  void clear();

 private:
  mutable std::mutex m_;
  std::vector<ValidationMessage> messages_;
  std::size_t errors_ = 0, warnings_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Devices.
struct DeviceInfo {
  int index = -1;  // in vkEnumeratePhysicalDevices order
  std::string name;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  std::string type_name;           // "discrete-gpu", "integrated-gpu", "virtual-gpu", "cpu", "other"
  std::string driver_name, driver_info;  // VkPhysicalDeviceDriverProperties ("llvmpipe", "Mesa 22.3.6 ...")
  std::uint32_t api_version = 0, driver_version = 0, vendor_id = 0, device_id = 0;
  VkPhysicalDeviceLimits limits{};  // maxStorageBufferRange, maxComputeWorkGroupCount, ...
  std::uint32_t subgroup_size = 0;
  // Loop iterations a shader invocation may run, all its loops together, before the driver ends
  // them silently; 0: no such limit. Mesa's llvmpipe: 65535 per SIMD batch of subgroup_size lanes.
  std::uint32_t loop_iteration_limit = 0;
  std::uint32_t timestamp_valid_bits = 0;  // of the compute queue family; 0: no timestamps
  std::uint64_t device_local_bytes = 0;    // largest device-local heap
  std::uint64_t max_allocation_bytes = 0;  // maxMemoryAllocationSize (0: the device does not say)
  bool is_gpu() const;
  std::string api_version_text() const;   // "1.3.230"
  std::string describe() const;            // "llvmpipe (LLVM 15.0.6, 256 bits) [cpu; llvmpipe Mesa ...; Vulkan 1.3.230]"
};

struct ContextOptions {
  // Device: a decimal index into list_devices(), or a case-insensitive substring of a device name.
  // Empty: $SOFTGI_VULKAN_DEVICE, and when that is unset too the best device: a discrete GPU, then
  // an integrated or virtual GPU, then a CPU device (lavapipe).
  std::string device;
  // 1 on, 0 off, -1: $SOFTGI_VULKAN_VALIDATION (0/1) when set, else on in Debug builds (no NDEBUG).
  // On requires VK_LAYER_KHRONOS_validation (an error naming it otherwise).
  int validation = -1;
  // A submission that has not completed within this time is an error (a GPU hang, or a shader
  // looping forever, becomes an exception instead of a frozen process).
  double fence_timeout_seconds = 120.0;
  // > 0: the per-invocation loop-iteration limit the shaders are written against, instead of the
  // driver's (DeviceInfo::loop_iteration_limit); a tighter one exercises the passes that respect it.
  std::uint32_t loop_iteration_limit = 0;
  // True: the shaders are run as on a device without a loop limit (DeviceInfo::loop_iteration_limit
  // 0, the budgets the passes pass their shaders at their largest), even where the driver has one.
  // This lets a CPU device run the code paths of a GPU's budgets; a loop that goes past the driver's
  // real limit is then cut silently, so it is only for work whose loops all fit within that limit.
  // Takes precedence over loop_iteration_limit.
  bool assume_no_loop_limit = false;
  // MemoryKind::Device buffers left unmapped even where the device's memory is the host's
  // (lavapipe), so that uploads and downloads go through staging copies and readbacks through
  // host copies, as on a discrete GPU: a CPU device then runs the code paths of one. -1:
  // $SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY (0/1) when set, else off.
  int unmapped_device_memory = -1;
};

// Every device the loader sees (through a temporary instance without layers).
std::vector<DeviceInfo> list_devices();
// The index into `devices` that `request` names (ContextOptions::device rules; "" = the best).
// Throws std::invalid_argument naming the request and listing every device.
int select_device(const std::vector<DeviceInfo>& devices, const std::string& request);

class Context;

// ---------------------------------------------------------------------------------------------
// RAII for any handle the helpers below do not wrap (render passes, framebuffers, graphics
// pipelines, samplers, ...): Owned<VkPipeline> p(h, [dev](VkPipeline x) { vkDestroyPipeline(dev, x, nullptr); });
template <class H>
class Owned {
 public:
  Owned() = default;
  Owned(H h, std::function<void(H)> destroy) : h_(h), destroy_(std::move(destroy)) {}
  ~Owned() { reset(); }
  Owned(Owned&& o) noexcept : h_(std::exchange(o.h_, H{})), destroy_(std::move(o.destroy_)) {}
  Owned& operator=(Owned&& o) noexcept {
    if (this != &o) {
      reset();
      h_ = std::exchange(o.h_, H{});
      destroy_ = std::move(o.destroy_);
    }
    return *this;
  }
  Owned(const Owned&) = delete;
  Owned& operator=(const Owned&) = delete;
  H get() const { return h_; }
  explicit operator bool() const { return h_ != H{}; }
  void reset() {
    if (h_ != H{} && destroy_) destroy_(h_);
    h_ = H{};
  }
  H release() { return std::exchange(h_, H{}); }  // gives up ownership without destroying

 private:
  H h_{};
  std::function<void(H)> destroy_;
};

// Where a buffer lives. Device: device-local; upload()/download() map it directly when the memory
// is also host-visible (lavapipe, integrated GPUs), else go through a staging buffer. Host:
// host-visible and coherent, persistently mapped (readback, per-frame constants).
enum class MemoryKind { Device, Host };

class Buffer {
 public:
  Buffer() = default;
  ~Buffer();
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }  // null when not host-visible
  const std::string& name() const { return name_; }
  explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  void release();
  Context* ctx_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
  std::string name_;
};

// A 2D image with one mip level and one layer, and a view of it.
class Image {
 public:
  Image() = default;
  ~Image();
  Image(Image&& o) noexcept;
  Image& operator=(Image&& o) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;
  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  VkFormat format() const { return format_; }
  std::uint32_t width() const { return width_; }
  std::uint32_t height() const { return height_; }
  const std::string& name() const { return name_; }
  explicit operator bool() const { return image_ != VK_NULL_HANDLE; }

 private:
  friend class Context;
  void release();
  Context* ctx_ = nullptr;
  VkImage image_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  std::uint32_t width_ = 0, height_ = 0;
  std::string name_;
};

// ---------------------------------------------------------------------------------------------
// SPIR-V reflection: the one source of truth for descriptor layouts is the shader itself.
struct ReflectedBinding {
  std::uint32_t set = 0, binding = 0;
  VkDescriptorType type = VK_DESCRIPTOR_TYPE_MAX_ENUM;
  std::uint32_t count = 1;           // array size (1 for a single resource)
  VkShaderStageFlags stages = 0;
  std::string name;                  // variable (or block type) name when the module carries names
};
struct ShaderReflection {
  VkShaderStageFlagBits stage = VK_SHADER_STAGE_COMPUTE_BIT;
  std::string entry_point = "main";
  std::vector<ReflectedBinding> bindings;  // sorted by (set, binding)
  std::uint32_t push_constant_size = 0;    // bytes (0: none)
  std::uint32_t local_size[3] = {1, 1, 1}; // compute shaders: OpExecutionMode LocalSize
};
// Parses OpEntryPoint, OpExecutionMode LocalSize, OpDecorate DescriptorSet/Binding/Block/BufferBlock,
// OpMemberDecorate Offset, types and OpVariable storage classes. Throws std::invalid_argument for
// words that are not a SPIR-V module or use a resource kind it does not know.
ShaderReflection reflect_spirv(std::span<const std::uint32_t> words);

// Descriptor set layouts (sets 0..max, every set that any stage uses) and the push-constant range of
// a pipeline, from the reflections of all its stages (bindings shared by stages must agree).
class PipelineLayout {
 public:
  PipelineLayout(Context& ctx, const std::vector<ShaderReflection>& stages, const std::string& name);
  ~PipelineLayout();
  PipelineLayout(const PipelineLayout&) = delete;
  PipelineLayout& operator=(const PipelineLayout&) = delete;
  VkPipelineLayout handle() const { return layout_; }
  std::uint32_t set_count() const { return static_cast<std::uint32_t>(sets_.size()); }
  VkDescriptorSetLayout set_layout(std::uint32_t set) const { return sets_.at(set); }
  const std::vector<ReflectedBinding>& bindings() const { return bindings_; }
  std::uint32_t push_constant_size() const { return push_size_; }
  VkShaderStageFlags push_constant_stages() const { return push_stages_; }
  const std::string& name() const { return name_; }

 private:
  Context& ctx_;
  std::string name_;
  std::vector<ReflectedBinding> bindings_;
  std::vector<VkDescriptorSetLayout> sets_;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  std::uint32_t push_size_ = 0;
  VkShaderStageFlags push_stages_ = 0;
};

// Specialization constant (constant_id, 32-bit value).
struct SpecConstant {
  std::uint32_t id = 0;
  std::uint32_t value = 0;
};

class ComputePipeline {
 public:
  ComputePipeline(Context& ctx, std::span<const std::uint32_t> spirv, const std::string& name,
                  const std::vector<SpecConstant>& spec = {});
  ~ComputePipeline();
  ComputePipeline(const ComputePipeline&) = delete;
  ComputePipeline& operator=(const ComputePipeline&) = delete;
  VkPipeline handle() const { return pipeline_; }
  const PipelineLayout& layout() const { return *layout_; }
  const ShaderReflection& reflection() const { return reflection_; }
  const std::string& name() const { return name_; }
  // Workgroups needed to cover `items` invocations along x with the shader's local size.
  std::uint32_t groups_x(std::size_t items) const;

 private:
  Context& ctx_;
  std::string name_;
  ShaderReflection reflection_;
  std::unique_ptr<PipelineLayout> layout_;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

// The render passes of softgi's rasterising passes: one subpass whose attachments are cleared, drawn
// into, and then copied out by transfer commands (colour attachments always; the depth attachment
// when copy_depth, else it is dropped). Ordered after the previous use's copies and depth writes.
struct RenderPassDesc {
  std::string name;  // in errors and debug labels
  std::vector<VkFormat> colors;
  VkFormat depth = VK_FORMAT_UNDEFINED;  // none
  bool copy_depth = false;
};
Owned<VkRenderPass> create_render_pass(Context& ctx, const RenderPassDesc& d);
// A framebuffer of `pass` over `views` (in the pass's attachment order), width x height, one layer.
Owned<VkFramebuffer> create_framebuffer(Context& ctx, VkRenderPass pass, const std::vector<VkImageView>& views, std::uint32_t width,
                                        std::uint32_t height, const std::string& name);

// The graphics pipelines of softgi's rasterising passes (the G-buffer, depth maps, splats): triangle
// lists without vertex input (the vertex shader fetches its corners from buffers), one sample at the
// pixel centre, one viewport and scissor set when recording.
struct GraphicsPipelineDesc {
  std::string name;  // in errors and debug labels
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkRenderPass render_pass = VK_NULL_HANDLE;
  VkShaderModule vertex = VK_NULL_HANDLE, fragment = VK_NULL_HANDLE;  // fragment: none for depth only
  std::string vertex_entry = "main", fragment_entry = "main";
  const VkSpecializationInfo* fragment_spec = nullptr;
  VkCullModeFlags cull = VK_CULL_MODE_NONE;
  VkFrontFace front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  const VkPipelineDepthStencilStateCreateInfo* depth = nullptr;  // null: the subpass has no depth attachment
  std::vector<VkPipelineColorBlendAttachmentState> blend;        // one per colour attachment
};
Owned<VkPipeline> create_graphics_pipeline(Context& ctx, const GraphicsPipelineDesc& d);
// Every channel written, no blending: one GraphicsPipelineDesc::blend entry.
VkPipelineColorBlendAttachmentState write_all_channels();

// Bytes per texel of the uncompressed formats softgi uses (0: not known).
std::uint64_t texel_bytes(VkFormat f);

// ---------------------------------------------------------------------------------------------
// Recording. A resource bound to one binding of a descriptor set.
struct Bind {
  std::uint32_t binding = 0;
  const Buffer* buffer = nullptr;
  VkDeviceSize offset = 0, range = VK_WHOLE_SIZE;
  const Image* image = nullptr;
  VkSampler sampler = VK_NULL_HANDLE;
  VkImageLayout image_layout = VK_IMAGE_LAYOUT_GENERAL;
  std::uint32_t set = 0;
  VkFormat texel_format = VK_FORMAT_UNDEFINED;  // a texel buffer binding: the view's format
  static Bind buffer_at(std::uint32_t binding, const Buffer& b, std::uint32_t set = 0) {
    Bind x;
    x.binding = binding;
    x.buffer = &b;
    x.set = set;
    return x;
  }
  // A storage buffer read through a texel buffer view of `format` (samplerBuffer, texelFetch): a
  // SIMD device such as llvmpipe fetches texels for all lanes at once, where it reads a storage
  // buffer lane by lane with a bounds check per component.
  static Bind texels_at(std::uint32_t binding, const Buffer& b, VkFormat format, std::uint32_t set = 0) {
    Bind x = buffer_at(binding, b, set);
    x.texel_format = format;
    return x;
  }
};

class Recorder {
 public:
  VkCommandBuffer cmd() const { return cmd_; }
  Context& context() const { return ctx_; }
  // A descriptor set for `set` of `layout` holding `binds` (valid until this submission completes).
  // Every binding the shaders declare in that set must be given, with a resource of the declared
  // kind: std::invalid_argument naming the pipeline and binding otherwise.
  VkDescriptorSet descriptor_set(const PipelineLayout& layout, std::uint32_t set, const std::vector<Bind>& binds);
  // Binds the pipeline and descriptor sets of every set the shader uses, pushes `push_bytes` bytes of
  // push constants (must equal the shader's block size), and dispatches. Group counts above the
  // device's limits are std::invalid_argument.
  void dispatch(const ComputePipeline& p, const std::vector<Bind>& binds, const void* push, std::uint32_t push_bytes,
                std::uint32_t gx, std::uint32_t gy = 1, std::uint32_t gz = 1);
  template <class T>
  void dispatch(const ComputePipeline& p, const std::vector<Bind>& binds, const T& push, std::uint32_t gx,
                std::uint32_t gy = 1, std::uint32_t gz = 1) {
    dispatch(p, binds, &push, static_cast<std::uint32_t>(sizeof(T)), gx, gy, gz);
  }
  // Every memory write recorded before is visible to every read and write recorded after (compute,
  // transfer, vertex/fragment, host).
  void barrier();
  void copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes, VkDeviceSize src_offset = 0,
            VkDeviceSize dst_offset = 0);
  void fill(const Buffer& dst, std::uint32_t value);  // whole buffer
  // A named GPU interval (timestamp pair) reported in SubmitResult::timers; intervals may not nest.
  void begin_timer(const std::string& label);
  void end_timer();

 private:
  friend class Context;
  Recorder(Context& ctx, VkCommandBuffer cmd) : ctx_(ctx), cmd_(cmd) {}
  Context& ctx_;
  VkCommandBuffer cmd_;
  std::vector<std::string> timer_labels_;
  bool timer_open_ = false;
  std::vector<VkBufferView> views_;  // texel views of this submission; Context::submit destroys them
};

struct SubmitResult {
  double gpu_seconds = -1.0;  // first to last command, from timestamps; -1 without timestamp support
  double wait_seconds = 0.0;  // host wall time from vkQueueSubmit to the fence (execution as the host sees it)
  std::vector<std::pair<std::string, double>> timers;
};

// The host copy of Context::upload and download into and out of mapped memory: std::memcpy below
// a few MB, above in 1 MB blocks on every core (a frame's display planes are tens of MB, and one
// core's copy moves less than half of what two do: bench_gbuffer's BM_HostCopy).
void copy_bytes(void* dst, const void* src, std::size_t bytes);

// ---------------------------------------------------------------------------------------------
class Context : public render::Device {
 public:
  explicit Context(const ContextOptions& options = {});
  ~Context() override;
  std::string backend_name() const override;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device_info() const { return info_; }
  bool validation_enabled() const { return validation_; }
  // Never null; outlives the Context when a caller keeps it (leaks are reported at destruction).
  const std::shared_ptr<ValidationLog>& validation_log() const { return log_; }

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  std::uint32_t queue_family() const { return queue_family_; }  // graphics + compute + transfer
  double fence_timeout_seconds() const { return fence_timeout_; }

  // Storage buffers larger than the device's maxStorageBufferRange, buffers larger than its
  // maxMemoryAllocationSize or its device memory, and any size 0, are std::invalid_argument naming
  // the buffer, the size and the limit (never a driver error); a failed allocation is a VulkanError
  // naming the buffer, its size and the memory heap. usage gets TRANSFER_SRC | TRANSFER_DST added.
  Buffer create_buffer(VkDeviceSize bytes, VkBufferUsageFlags usage, MemoryKind kind, const std::string& name);
  // Reallocates `b` only when it is smaller than `bytes` (per-frame buffers reused across frames).
  void ensure_buffer(Buffer& b, VkDeviceSize bytes, VkBufferUsageFlags usage, MemoryKind kind, const std::string& name);
  void upload(const Buffer& dst, const void* src, std::size_t bytes, std::size_t dst_offset = 0);
  void download(const Buffer& src, void* dst, std::size_t bytes, std::size_t src_offset = 0);
  template <class T>
  Buffer upload_vector(const std::vector<T>& v, VkBufferUsageFlags usage, const std::string& name) {
    Buffer b = create_buffer(std::max<std::size_t>(1, v.size()) * sizeof(T), usage, MemoryKind::Device, name);
    if (!v.empty()) upload(b, v.data(), v.size() * sizeof(T));
    return b;
  }
  // Images beyond maxImageDimension2D, or whose texels exceed maxMemoryAllocationSize or the
  // format's maxResourceSize, are std::invalid_argument naming the image, the size and the limit; a
  // failed allocation is a VulkanError naming the image, its size and the memory heap.
  Image create_image(std::uint32_t width, std::uint32_t height, VkFormat format, VkImageUsageFlags usage,
                     VkImageAspectFlags aspect, const std::string& name);
  Owned<VkShaderModule> create_shader_module(std::span<const std::uint32_t> spirv, const std::string& name);
  // Labels an object for validation messages and GPU debuggers (no-op without debug utils).
  void set_name(VkObjectType type, std::uint64_t handle, const std::string& name) const;

  // Records with `record`, submits to the queue and waits on a fence (fence_timeout_seconds, then a
  // VulkanError naming `what`). Timestamps bracket the commands when the queue supports them.
  SubmitResult submit(const std::function<void(Recorder&)>& record, const std::string& what);
  // Sum of SubmitResult::gpu_seconds and number of submissions since the Context was created.
  double gpu_seconds_total() const { return gpu_total_; }
  double wait_seconds_total() const { return wait_total_; }  // sum of SubmitResult::wait_seconds
  std::uint64_t submissions() const { return submissions_; }
  std::size_t allocated_bytes() const { return allocated_; }  // buffers alive
  // Whether MemoryKind::Device buffers are host-visible (mapped) on this device: lavapipe and most
  // integrated GPUs, whose device memory is the host's; a discrete GPU's is not.
  bool device_buffers_mapped() const;
  // Bytes moved between host and device memory: every upload() and download(), and what callers
  // that write or read mapped memory themselves report through note_transfer().
  render::TransferBytes transfer_bytes() const { return transfer_; }
  void note_transfer(std::size_t upload_bytes, std::size_t download_bytes) {
    transfer_.upload += upload_bytes;
    transfer_.download += download_bytes;
  }

  // Per-context cache of GPU objects kept across frames (pipelines, uploaded tables), keyed by
  // name; destroyed with the Context, before its device.
  template <class T>
  std::shared_ptr<T> cached(const std::string& key, const std::function<std::shared_ptr<T>()>& make) {
    std::lock_guard<std::mutex> lock(cache_mutex_);
    auto it = cache_.find(key);
    if (it != cache_.end()) return std::static_pointer_cast<T>(it->second);
    std::shared_ptr<T> v = make();
    cache_[key] = v;
    return v;
  }
  void clear_cache();

  // Test-only: creates a VkBuffer and never destroys it, so that validation reports a leaked object
  // when the device is destroyed (the leak check's own test).
  void leak_buffer_for_test();

 private:
  friend class Buffer;
  friend class Image;
  friend class Recorder;
  std::uint32_t memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer) const;
  // `what` names the allocation in errors ("buffer 'shexp visibility'").
  VkDeviceMemory allocate(const VkMemoryRequirements& req, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer,
                          bool& host_visible, const std::string& what);
  VkDescriptorSet allocate_set(VkDescriptorSetLayout layout);
  void note_free(VkDeviceSize bytes) { allocated_ -= static_cast<std::size_t>(bytes); }
  // After a timed-out submission: waits (once, up to max(timeout, 30 s)) for it to finish before
  // anything it may use is destroyed. No-op otherwise.
  void settle();
  friend class PipelineLayout;
  friend class ComputePipeline;
  void destroy();

  ContextOptions options_;
  bool unmapped_device_ = false;  // ContextOptions::unmapped_device_memory, resolved
  DeviceInfo info_;
  bool validation_ = false;
  std::shared_ptr<ValidationLog> log_ = std::make_shared<ValidationLog>();
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  PFN_vkSetDebugUtilsObjectNameEXT set_name_fn_ = nullptr;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkPhysicalDeviceMemoryProperties memory_{};
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  VkQueryPool query_pool_ = VK_NULL_HANDLE;
  std::uint32_t query_capacity_ = 0, queries_used_ = 0;
  std::vector<VkDescriptorPool> descriptor_pools_;  // reset after every submission
  std::size_t pool_in_use_ = 0;
  double fence_timeout_ = 120.0;
  double gpu_total_ = 0.0, wait_total_ = 0.0;
  std::uint64_t submissions_ = 0;
  std::size_t allocated_ = 0;  // buffer bytes alive
  render::TransferBytes transfer_;
  bool lost_ = false;          // a submission timed out: no further submissions
  bool pending_ = false;       // ... and may still be executing
  std::mutex submit_mutex_;
  std::mutex cache_mutex_;
  std::map<std::string, std::shared_ptr<void>> cache_;
  std::vector<VkBuffer> leaked_for_test_;
};

// The Context of the Vulkan backend executing this frame (FrameContext::device). Throws
// std::logic_error when the frame is not run by it.
Context& context_of(render::FrameContext& frame);

}  // namespace softgi::backends::vulkan
