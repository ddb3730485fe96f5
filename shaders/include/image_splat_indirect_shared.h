// Constants of image_splat's accumulate_indirect shader (shaders/image_splat/accumulate_indirect.comp),
// shared by the C++ side (techniques/image_splat/image_splat_vulkan_shading.cpp) and GLSL.
#ifndef SOFTGI_IMAGE_SPLAT_INDIRECT_SHARED_H
#define SOFTGI_IMAGE_SPLAT_INDIRECT_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_II_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_II_CONST_UINT(name, value) const uint name = value;
#endif

SOFTGI_II_CONST_UINT(kIndGroup, 64u)  // receivers per workgroup
// Operators (image_splat::IndirectOperator).
SOFTGI_II_CONST_UINT(kIndOpPoint, 0u)
SOFTGI_II_CONST_UINT(kIndOpAveraged, 1u)  // averaged and averaged_poly: the D table differs, not the shader
SOFTGI_II_CONST_UINT(kIndOpExact, 2u)     // eqs. 16-17: reads the M blocks, the Q blocks and hc

// Floats of the indirect constants' uniform block (kIndBindConsts, kSplatIndBindConsts): 3 n^2 + 2 n
// for n up to kAccumMaxOrder (8: 208), a multiple of 4 (std140 carries them as vec4s).
SOFTGI_II_CONST_UINT(kIndConstFloats, 208u)
// accumulate_indirect bindings (set 0)
SOFTGI_II_CONST_UINT(kIndBindReceivers, 0u)     // float[6 * count]: px, py, pz, nx, ny, nz planes
SOFTGI_II_CONST_UINT(kIndBindReceiverList, 1u)  // uint per receiver: index of its tile's proxy list
SOFTGI_II_CONST_UINT(kIndBindListRange, 2u)     // uvec2 per tile: (first proxy, count)
SOFTGI_II_CONST_UINT(kIndBindProxies, 3u)       // vec4 per proxy: centre, radius
SOFTGI_II_CONST_UINT(kIndBindAlbedo, 4u)        // vec4 per proxy: albedo / pi, 0
SOFTGI_II_CONST_UINT(kIndBindVis, 5u)           // IndirectEvaluator visibility ZhTable::data
SOFTGI_II_CONST_UINT(kIndBindDfac, 6u)          // rows * n D factors (averaged), 1 float otherwise
SOFTGI_II_CONST_UINT(kIndBindConsts, 7u)        // uniform block of kIndConstFloats: L~ (3 n^2, coefficient-major), vh (n), hc (n), zeros
SOFTGI_II_CONST_UINT(kIndBindBasis, 8u)         // shexp basis recurrence constants (asin included)
SOFTGI_II_CONST_UINT(kIndBindOut, 9u)           // float[4 * count]: rgb, omega
SOFTGI_II_CONST_UINT(kIndBindPairs, 10u)        // uint: receiver-proxy pairs inside the sphere of influence
// Exact only (1 float otherwise). The shader walks both in the evaluator's order and derives the
// offsets (TableView::moff, mrow, qoff) as running sums; the host checks they agree.
SOFTGI_II_CONST_UINT(kIndBindMtab, 11u)         // TableView::mtab: rows x mrow, the m-blocks of M per row
SOFTGI_II_CONST_UINT(kIndBindQrot, 12u)         // TableView::qrot: band blocks of Rot(Q), Q = Rx(-90 deg)

#undef SOFTGI_II_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
