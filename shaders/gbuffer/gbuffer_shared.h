// Constants shared by the G-buffer rasterisation pass (backends/vulkan/gbuffer_raster.cpp) and its
// shaders (gbuffer_raster.vert / .frag): one declaration, included by both (the pattern of
// shaders/include/softgi_shared.h).
#ifndef SOFTGI_GBUFFER_SHARED_H
#define SOFTGI_GBUFFER_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_GB_CONST(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_GB_CONST(name, value) const uint name = value;
#endif

// Descriptor set 0.
SOFTGI_GB_CONST(kGbBindFrame, 0u)      // uniform GbFrame: clip_from_world, camera basis, image sizes
SOFTGI_GB_CONST(kGbBindPositions, 1u)  // float[3 * vertices]: posed world-space positions, every object
SOFTGI_GB_CONST(kGbBindNormals, 2u)    // float[3 * vertices]: posed world-space vertex normals (0 where absent)
SOFTGI_GB_CONST(kGbBindIndices, 3u)    // uint[3 * triangles]: vertex indices into the arrays above

// Colour attachments (fragment outputs).
SOFTGI_GB_CONST(kGbOutPositionDepth, 0u)  // RGBA32F: world position, eye-space depth (p - e) . E
SOFTGI_GB_CONST(kGbOutNormal, 1u)         // RGBA32F: shading normal (w unused)
SOFTGI_GB_CONST(kGbOutIds, 2u)            // RG32I: object, primitive (-1, -1 = background)
SOFTGI_GB_CONST(kGbOutBarycentric, 3u)    // RG32F: (b1, b2)
SOFTGI_GB_CONST(kGbColorAttachments, 4u)

#undef SOFTGI_GB_CONST
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
