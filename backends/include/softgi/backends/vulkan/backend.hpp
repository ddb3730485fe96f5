// The Vulkan backend: the same pass graphs as the CPU backend, each pass running its Vulkan
// implementation where it has one and its host implementation otherwise (tables, hierarchy, cuts,
// image composition). GPU passes record into the backend's vulkan::Context (FrameContext::device)
// and report the GPU time of their submissions (timestamps) in PassRecord::gpu_seconds, next to the
// wall time, and their host <-> device bytes in PassRecord::transfer.
// Deliberately free of <vulkan/vulkan.h> (the application includes this header).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>

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

 protected:
  void execute_pass(const render::PassDesc& pass, render::FrameContext& ctx) override;
  render::TransferBytes transfer_total() const override;

 private:
  std::shared_ptr<vulkan::Context> ctx_;
};

// Registers the backend (render::register_backend: available when a Vulkan device can be created)
// and its implementations of the shared passes: "gbuffer" and "receiver_gbuffer" are the
// rasterisation pipeline (backends/vulkan/gbuffer_raster.cpp). Idempotent.
void register_vulkan_backend();

}  // namespace softgi::backends
