// Shared by point_voxels' Vulkan files (pv_vulkan.cpp, pv_depth_vulkan.cpp). Includes the Vulkan
// headers: include only from *_vulkan.cpp files. Not installed.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "pv_passes.hpp"
#include "softgi/backends/vulkan/context.hpp"

namespace softgi::techniques::point_voxels {

// The lights' depth maps on the device: every local light's six faces (size^2 floats each, as
// CubeDepthMap::depth), and the sun's map after a header of kPvSunHeader floats (dir, u, v, lo,
// extent, size), as vpl_light.comp reads them. The hashes are those of the last host upload (0 after
// the device wrote the buffers).
struct LightBuffers {
  backends::vulkan::Buffer cube, sun;
  std::uint64_t cube_hash = 0, sun_hash = 0;
};

// The sun map's header as vpl_light.comp reads it (kPvSunHeader floats: dir, u, v, lo, extent,
// size; zeros without a sun).
std::vector<float> sun_header(const Lights& L);

// Rasterises the depth maps of `lights` (planned by the host: centres, the sun's frame) into `out`
// (pv_depth_vulkan.cpp). Records the pass's counters; puts nothing.
void vulkan_light_maps(const Settings& s, render::FrameContext& ctx, std::shared_ptr<Lights> lights, LightBuffers& out);

}  // namespace softgi::techniques::point_voxels
