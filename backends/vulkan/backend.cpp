#include "softgi/backends/vulkan/backend.hpp"

#include <iomanip>
#include <mutex>
#include <sstream>

#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/frame.hpp"
#include "gbuffer_raster.hpp"

namespace softgi::backends {

namespace {
vulkan::ContextOptions to_options(const VulkanBackendOptions& o) {
  vulkan::ContextOptions c;
  c.device = o.device;
  c.validation = o.validation;
  c.fence_timeout_seconds = o.fence_timeout_seconds;
  return c;
}
}  // namespace

VulkanBackend::VulkanBackend(const VulkanBackendOptions& options)
    : VulkanBackend(std::make_shared<vulkan::Context>(to_options(options))) {
  set_memory_limit(options.memory_limit);
}

VulkanBackend::VulkanBackend(std::shared_ptr<vulkan::Context> context) : ctx_(std::move(context)) {
  if (!ctx_) throw std::invalid_argument("VulkanBackend: null context");
}

render::Device* VulkanBackend::device() { return ctx_.get(); }

render::TransferBytes VulkanBackend::transfer_total() const { return ctx_->transfer_bytes(); }

VulkanBackend::~VulkanBackend() = default;

std::string VulkanBackend::device_name() const { return ctx_->device_info().name; }

std::map<std::string, std::string> VulkanBackend::device_record() const {
  const vulkan::DeviceInfo& d = ctx_->device_info();
  std::ostringstream vendor, device;
  vendor << "0x" << std::hex << std::setw(4) << std::setfill('0') << d.vendor_id;
  device << "0x" << std::hex << std::setw(4) << std::setfill('0') << d.device_id;
  return {{"name", d.name},
          {"index", std::to_string(d.index)},
          {"type", d.type_name},
          {"driver", d.driver_name},
          {"driver_info", d.driver_info},
          {"api_version", d.api_version_text()},
          {"vendor_id", vendor.str()},
          {"device_id", device.str()},
          {"validation", ctx_->validation_enabled() ? "on" : "off"}};
}

render::MemoryLimits VulkanBackend::memory_limits() const {
  render::MemoryLimits l = render::host_memory_limits(memory_limit());
  if (!l.checked) return l;
  const vulkan::DeviceInfo& d = ctx_->device_info();
  l.max_storage_buffer = d.limits.maxStorageBufferRange;
  l.max_allocation = static_cast<std::size_t>(d.max_allocation_bytes);
  l.device_is_host_memory = d.type == VK_PHYSICAL_DEVICE_TYPE_CPU;
  // A CPU device's memory is the host's: the host check counts host and device items together.
  if (l.device_is_host_memory) return l;
  if (l.declared) {
    l.device = l.host;
    l.device_source = l.host_source;
  } else {
    l.device = static_cast<std::size_t>(d.device_local_bytes);
    l.device_source = "the largest device-local memory heap";
  }
  return l;
}

void VulkanBackend::add_backend_memory(const std::vector<const render::PassDesc*>& passes, const scene::Scene& scene,
                                       const render::ParamSet& params, int width, int height,
                                       std::vector<render::MemoryItem>& items) const {
  gbuffer_raster_memory(passes, scene, params, width, height, !ctx_->device_buffers_mapped(), items);
}

void VulkanBackend::execute_pass(const render::PassDesc& pass, render::FrameContext& ctx) {
  const double gpu0 = ctx_->gpu_seconds_total(), wait0 = ctx_->wait_seconds_total();
  const std::uint64_t sub0 = ctx_->submissions();
  render::Backend::execute_pass(pass, ctx);
  // GPU time of the pass: the timestamped span of every submission it made (host passes have none).
  if (ctx_->submissions() != sub0) {
    ctx.record().gpu_seconds = ctx_->gpu_seconds_total() - gpu0;
    ctx.record().counters["gpu_submissions"] = static_cast<double>(ctx_->submissions() - sub0);
    // Submission to fence, as the host waited: on lavapipe the timestamps of some compute
    // dispatches do not bracket their execution (docs/backends.md), this does.
    ctx.record().counters["gpu_wait_seconds"] = ctx_->wait_seconds_total() - wait0;
  }
}

void register_vulkan_backend() {
  static std::once_flag once;
  std::call_once(once, [] {
    render::BackendInfo info;
    info.name = vulkan::kBackendName;
    info.description = "Vulkan compute and rasterisation (a GPU, or Mesa lavapipe on the CPU)";
    info.selects_device = true;
    // No loader, no driver or no device with compute: the reason, as the loader reported it.
    info.unavailable = []() -> std::string {
      try {
        if (vulkan::list_devices().empty()) return "no Vulkan device (install a driver, e.g. Mesa's lavapipe)";
        return {};
      } catch (const std::exception& e) {
        return e.what();
      }
    };
    info.create = [](const render::BackendOptions& o) -> std::unique_ptr<render::Backend> {
      VulkanBackendOptions vo;
      vo.device = o.device;
      vo.validation = o.validation;
      vo.memory_limit = o.memory_limit;
      return std::make_unique<VulkanBackend>(vo);
    };
    render::register_backend(std::move(info));
    register_gbuffer_raster_passes();
  });
}

}  // namespace softgi::backends
