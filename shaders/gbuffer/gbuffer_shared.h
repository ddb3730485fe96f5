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

// Colour attachments (fragment outputs): a visibility buffer, what the rasteriser alone decides.
SOFTGI_GB_CONST(kGbOutIds, 0u)            // RG32I: object, primitive (-1, -1 = background)
SOFTGI_GB_CONST(kGbOutBarycentric, 1u)    // RG32F: (b1, b2)
SOFTGI_GB_CONST(kGbColorAttachments, 2u)

// The resolve pass (gbuffer_resolve.comp): set 0 also binds these, the attachments copied to
// buffers and what it computes from them, one invocation per pixel.
SOFTGI_GB_CONST(kGbBindObjects, 4u)        // uvec2[objects]: first triangle in the index buffer, has normals
SOFTGI_GB_CONST(kGbBindIds, 5u)            // ivec2[pixels]: the kGbOutIds attachment
SOFTGI_GB_CONST(kGbBindBarycentric, 6u)    // vec2[pixels]: the kGbOutBarycentric attachment
SOFTGI_GB_CONST(kGbBindPositionDepth, 7u)  // vec4[pixels] out: world position, eye-space depth (p - e) . E
SOFTGI_GB_CONST(kGbBindNormal, 8u)         // vec4[pixels] out: shading normal (w unused)
SOFTGI_GB_CONST(kGbResolveGroup, 64u)      // invocations per workgroup

#undef SOFTGI_GB_CONST
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
