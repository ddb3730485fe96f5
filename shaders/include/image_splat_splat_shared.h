// Constants of image_splat's rasterised splats (shaders/image_splat/splat.vert, splat_log.frag,
// splat_gather.comp, splat_indirect.frag), shared by the C++ side (techniques/image_splat/image_splat_vulkan_splat.cpp)
// and GLSL.
#ifndef SOFTGI_IMAGE_SPLAT_SPLAT_SHARED_H
#define SOFTGI_IMAGE_SPLAT_SPLAT_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_IS_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#define SOFTGI_IS_CONST_FLOAT(name, value) inline constexpr float name = value;
#else
#define SOFTGI_IS_CONST_UINT(name, value) const uint name = value;
#define SOFTGI_IS_CONST_FLOAT(name, value) const float name = value;
#endif

// Colour attachments (RGBA32F, 4 coefficients each) one draw of the splats fills at most; higher
// orders draw again for the next coefficients.
SOFTGI_IS_CONST_UINT(kSplatMaxAttachments, 8u)
// The hull drawn for a sphere of influence of radius R bounds radius R (1 + kSplatHullMargin) plus a
// buffer pixel at the sphere's far depth: enough that the rasteriser's snapping of its vertices to
// the sub-pixel grid and the float rounding of the receivers' positions (on their pixel's ray to a
// few ulps) never leave out a receiver inside the sphere. Pixels the margin adds read exactly 0
// from the clamped table, or fail the per-pair cut.
SOFTGI_IS_CONST_FLOAT(kSplatHullMargin, 1.0e-2f)
SOFTGI_IS_CONST_UINT(kSplatGatherGroup, 64u)

// splat.vert / splat_log.frag bindings (set 0)
SOFTGI_IS_CONST_UINT(kSplatBindTest, 0u)        // vec4 per proxy: centre, radius of the sphere of influence (inf: everywhere)
SOFTGI_IS_CONST_UINT(kSplatBindHull, 1u)        // vec4 per hull vertex (triangle list, outward counter-clockwise), around the unit sphere
SOFTGI_IS_CONST_UINT(kSplatBindSpheres, 2u)     // vec4 per proxy: centre, radius
SOFTGI_IS_CONST_UINT(kSplatBindWeights, 3u)     // band weights, kAccWeightStride(N) floats per proxy
SOFTGI_IS_CONST_UINT(kSplatBindTable, 4u)       // log table: (value, slope) per row and band
SOFTGI_IS_CONST_UINT(kSplatBindBasis, 5u)       // basis recurrence constants (sh_basis.glsl)
SOFTGI_IS_CONST_UINT(kSplatBindReceivers, 6u)   // receiver planes px, py, pz, nx, ny, nz (count floats each)
SOFTGI_IS_CONST_UINT(kSplatBindPixelReceiver, 7u)  // int per buffer pixel: its receiver, -1 = background

// splat_indirect.frag bindings (set 0) besides kSplatBindTest, kSplatBindHull, kSplatBindBasis,
// kSplatBindReceivers and kSplatBindPixelReceiver: the flat proxy list and the evaluator's tables
// (image_splat_indirect_shared.h's layouts)
SOFTGI_IS_CONST_UINT(kSplatIndBindProxies, 8u)   // vec4 per proxy: centre, radius
SOFTGI_IS_CONST_UINT(kSplatIndBindAlbedo, 9u)    // vec4 per proxy: albedo / pi
SOFTGI_IS_CONST_UINT(kSplatIndBindVis, 10u)
SOFTGI_IS_CONST_UINT(kSplatIndBindDfac, 11u)
SOFTGI_IS_CONST_UINT(kSplatIndBindConsts, 12u)
SOFTGI_IS_CONST_UINT(kSplatIndBindMtab, 13u)
SOFTGI_IS_CONST_UINT(kSplatIndBindQrot, 14u)
SOFTGI_IS_CONST_UINT(kSplatIndBindPairs, 15u)    // uint: pairs counted (inside the sphere of influence)

// splat_gather.comp bindings (set 0)
SOFTGI_IS_CONST_UINT(kSplatGatherBindRaw, 0u)    // vec4 per (attachment of all draws, buffer pixel)
SOFTGI_IS_CONST_UINT(kSplatGatherBindPixel, 1u)  // int per receiver: its buffer pixel
SOFTGI_IS_CONST_UINT(kSplatGatherBindOut, 2u)    // n^2 floats per receiver

#undef SOFTGI_IS_CONST_UINT
#undef SOFTGI_IS_CONST_FLOAT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
