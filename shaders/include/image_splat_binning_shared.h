// Constants of image_splat's binning shader (shaders/image_splat/bin_proxies.comp), shared by the C++
// side (techniques/image_splat/image_splat_vulkan_binning.cpp) and GLSL.
#ifndef SOFTGI_IMAGE_SPLAT_BINNING_SHARED_H
#define SOFTGI_IMAGE_SPLAT_BINNING_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_IB_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_IB_CONST_UINT(name, value) const uint name = value;
#endif

// One invocation per receiver tile, kBinGroup tiles per workgroup.
SOFTGI_IB_CONST_UINT(kBinGroup, 64u)
// Modes (push constant `mode`).
SOFTGI_IB_CONST_UINT(kBinCount, 0u)    // count[tile] += proxies of [first, end) that reach the tile
SOFTGI_IB_CONST_UINT(kBinScatter, 1u)  // write them, in proxy order, from range.x + count[tile] on (count[tile]: written so far)
SOFTGI_IB_CONST_UINT(kBinMaxPayload, 2u)  // vec4s of payload b per proxy at most

// bindings (set 0)
SOFTGI_IB_CONST_UINT(kBinBindTiles, 0u)    // 2 vec4 per tile: box lo, box hi (w unused)
SOFTGI_IB_CONST_UINT(kBinBindTest, 1u)     // vec4 per proxy: centre, radius of the sphere of influence
SOFTGI_IB_CONST_UINT(kBinBindSrcA, 2u)     // vec4 per proxy: copied to dst_a (centre, radius)
SOFTGI_IB_CONST_UINT(kBinBindSrcB, 3u)     // `payload` vec4s per proxy: copied to dst_b (band weights, albedo)
SOFTGI_IB_CONST_UINT(kBinBindCount, 4u)    // uint per tile: proxies counted (count) or written so far (scatter)
SOFTGI_IB_CONST_UINT(kBinBindRanges, 5u)   // uvec2 per tile: (first entry, count) (scatter)
SOFTGI_IB_CONST_UINT(kBinBindDstA, 6u)     // vec4 per entry (scatter)
SOFTGI_IB_CONST_UINT(kBinBindDstB, 7u)     // `payload` vec4s per entry (scatter)
SOFTGI_IB_CONST_UINT(kBinBindIndex, 8u)    // uint per entry: the proxy's index in the flat list (scatter)

#undef SOFTGI_IB_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
