// Vulkan implementations of the shared passes (common_passes.hpp). "compose" carries its own
// implementation for both backends; "gbuffer" on Vulkan is the rasterisation pipeline, registered
// here once it exists (brief V2). Until then a technique that needs the G-buffer on the Vulkan
// backend fails with "pass 'gbuffer' has no implementation for the vulkan backend".
#include "softgi/backends/vulkan/backend.hpp"
#include "gbuffer_raster.hpp"

namespace softgi::backends {

void register_vulkan_shared_passes() { register_gbuffer_raster_passes(); }

}  // namespace softgi::backends
