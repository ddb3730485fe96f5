// The Vulkan implementations of the shared passes "gbuffer" and "receiver_gbuffer"
// (softgi/render/common_passes.hpp): a graphics pipeline rasterises every posed object into a
// G-buffer (gbuffer_raster.cpp). Private to softgi::vulkan; register_vulkan_backend calls it.
#pragma once

namespace softgi::backends {

// Registers "gbuffer" and "receiver_gbuffer" for the Vulkan backend (render::register_shared_pass_impl).
void register_gbuffer_raster_passes();

}  // namespace softgi::backends
