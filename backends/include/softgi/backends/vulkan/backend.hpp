// The Vulkan backend: the same pass graphs as the CPU backend, each pass running its Vulkan
// implementation where it has one and its host implementation otherwise (tables, hierarchy, cuts,
// image composition). GPU passes record into the backend's vulkan::Context (FrameContext::device)
// and report the GPU time of their submissions (timestamps) in PassRecord::gpu_seconds, next to the
// wall time, and their host <-> device bytes in PassRecord::transfer.
// Deliberately free of <vulkan/vulkan.h> (the application includes this header).
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "softgi/render/backend.hpp"

namespace softgi::backends {

namespace vulkan {
class Context;
// The backend's name in the registry, in PassDesc::impl and in run records.
inline constexpr const char* kBackendName = "vulkan";
}

struct VulkanBackendOptions {
  std::string device;                  // vulkan::ContextOptions::device ("" = $SOFTGI_VULKAN_DEVICE, else the best)
  int validation = -1;                 // vulkan::ContextOptions::validation
  double fence_timeout_seconds = 120.0;
  std::size_t memory_limit = 0;        // render::Backend::set_memory_limit (0: the machine's, or SOFTGI_MEMORY_LIMIT)
};

class VulkanBackend : public render::Backend {
 public:
  // Creates the instance and device (errors name the device request and list the devices).
  explicit VulkanBackend(const VulkanBackendOptions& options = {});
  explicit VulkanBackend(std::shared_ptr<vulkan::Context> context);
  ~VulkanBackend() override;
  std::string name() const override { return vulkan::kBackendName; }
  render::Device* device() override;
  vulkan::Context& context() { return *ctx_; }
  const std::shared_ptr<vulkan::Context>& shared_context() const { return ctx_; }
  // For run records: name, type, driver, driver_info, api_version, vendor_id, device_id, index.
  std::map<std::string, std::string> device_record() const override;
  std::string device_name() const;
  // The host's limits (render::host_memory_limits) and the device's: maxStorageBufferRange per
  // storage buffer, maxMemoryAllocationSize per allocation, and the largest device-local heap for
  // the total, except on a CPU device (lavapipe), whose memory is process memory: there the host's
  // limit covers host and device items together (lavapipe's heap size is not enforced). A declared
  // limit (set_memory_limit, SOFTGI_MEMORY_LIMIT) replaces the host's and the heap's totals.
  render::MemoryLimits memory_limits() const override;

 protected:
  void execute_pass(const render::PassDesc& pass, render::FrameContext& ctx) override;
  render::TransferBytes transfer_total() const override;
  // The rasteriser's attachments, readback and geometry buffers for "gbuffer" and
  // "receiver_gbuffer" (gbuffer_raster.cpp).
  void add_backend_memory(const std::vector<const render::PassDesc*>& passes, const scene::Scene& scene, const render::ParamSet& params,
                          int width, int height, std::vector<render::MemoryItem>& items) const override;
  std::string memory_device_name() const override { return device_name(); }

 private:
  std::shared_ptr<vulkan::Context> ctx_;
};

// Registers the backend (render::register_backend: available when a Vulkan device can be created)
// and its implementations of the shared passes: "gbuffer" and "receiver_gbuffer" are the
// rasterisation pipeline (backends/vulkan/gbuffer_raster.cpp). Idempotent.
void register_vulkan_backend();

}  // namespace softgi::backends
