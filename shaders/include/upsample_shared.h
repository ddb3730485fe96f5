// Constants of the upsampling shaders (shaders/common/upsample_*.comp, paper 000 section 4.2),
// shared by the C++ side (techniques/common/upsample_vulkan.cpp) and GLSL: one declaration,
// included by both.
#ifndef SOFTGI_UPSAMPLE_SHARED_H
#define SOFTGI_UPSAMPLE_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_UP_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_UP_CONST_UINT(name, value) const uint name = value;
#endif

// Workgroup size of the per-display-pixel passes (8 x 8 pixels).
SOFTGI_UP_CONST_UINT(kUpsampleGroupX, 8u)
SOFTGI_UP_CONST_UINT(kUpsampleGroupY, 8u)
// Upsampling modes (common::UpsampleMode).
SOFTGI_UP_CONST_UINT(kUpsampleBilateral, 0u)
SOFTGI_UP_CONST_UINT(kUpsampleBilinear, 1u)

// upsample_weights bindings (set 0)
SOFTGI_UP_CONST_UINT(kUpBindFine, 0u)    // vec4 per display pixel: normal (xyz) and depth (w)
SOFTGI_UP_CONST_UINT(kUpBindCoarse, 1u)  // vec4 per coarse pixel: normal (xyz) and depth (w)
SOFTGI_UP_CONST_UINT(kUpBindIndex, 2u)   // ivec4 per display pixel (-1 = unused, packed to the front)
SOFTGI_UP_CONST_UINT(kUpBindWeight, 3u)  // vec4 per display pixel
SOFTGI_UP_CONST_UINT(kUpBindMiss, 4u)    // uvec2 per display pixel: (miss, bits of the eq. 11 measure)
SOFTGI_UP_CONST_UINT(kUpBindSurface, 5u) // uint per display pixel that sees a surface: its index (the invocations)
SOFTGI_UP_CONST_UINT(kUpWeightsGroup, 64u)

// upsample_apply bindings (set 0)
SOFTGI_UP_CONST_UINT(kApBindIndex, 0u)
SOFTGI_UP_CONST_UINT(kApBindWeight, 1u)
SOFTGI_UP_CONST_UINT(kApBindIn, 2u)   // channels floats per coarse pixel
SOFTGI_UP_CONST_UINT(kApBindOut, 3u)  // channels floats per listed pixel, in list order
SOFTGI_UP_CONST_UINT(kApBindList, 4u) // uint per display pixel with a tap: its index (the invocations)

#undef SOFTGI_UP_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
