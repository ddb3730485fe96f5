// The Vulkan implementations of the shared passes "gbuffer" and "receiver_gbuffer"
// (softgi/render/common_passes.hpp): a graphics pipeline rasterises every posed object into a
// G-buffer (gbuffer_raster.cpp). Private to softgi::vulkan; register_vulkan_backend calls it.
#pragma once

#include <vector>

#include "softgi/render/backend.hpp"

namespace softgi::backends {

// The device memory the rasteriser allocates for the frame's "gbuffer" and "receiver_gbuffer"
// passes (attachments, readback buffers, geometry), for render::Backend::estimate_memory.
// `resolved_readback`: the device's buffers are not mapped (Context::device_buffers_mapped), so the
// resolved planes have host copies to read back through.
void gbuffer_raster_memory(const std::vector<const render::PassDesc*>& passes, const scene::Scene& scene,
                           const render::ParamSet& params, int width, int height, bool resolved_readback,
                           std::vector<render::MemoryItem>& items);

// Registers "gbuffer" and "receiver_gbuffer" for the Vulkan backend (render::register_shared_pass_impl).
void register_gbuffer_raster_passes();

}  // namespace softgi::backends
