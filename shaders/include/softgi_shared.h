// Constants shared by the C++ side and the GLSL shaders: one declaration, included by both.
// C++: inline constexpr values in softgi::gpu; GLSL: const values (usable in layout qualifiers).
#ifndef SOFTGI_SHARED_H
#define SOFTGI_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_CONST_UINT(name, value) const uint name = value;
#endif

// SHEXP (paper 004): the largest accumulation order a shader handles (shexp::kMaxAccOrder), and the
// largest coefficient count n^2 (per-invocation arrays are sized by it).
SOFTGI_CONST_UINT(kAccumMaxOrder, 8u)
SOFTGI_CONST_UINT(kAccumMaxCoeffs, 64u)
// Workgroup sizes (one invocation per receiver).
SOFTGI_CONST_UINT(kAccumulateGroup, 64u)
SOFTGI_CONST_UINT(kExponentiateGroup, 64u)
SOFTGI_CONST_UINT(kShadeGroup, 64u)
SOFTGI_CONST_UINT(kShadeConstFloats, 320u)  // 5 kAccumMaxCoeffs: shade.comp's uniform block of constants

// Layout of the SH basis-recurrence constant buffer (floats; the constants of the CPU kernel,
// shexp::basis_recurrence_constants): Q_m^m, a1, A[l][m], B[l][m] (row-major, kAccumMaxOrder wide),
// then the 8 coefficients of the asin polynomial (Abramowitz & Stegun 4.4.46).
SOFTGI_CONST_UINT(kBasisQmm, 0u)
SOFTGI_CONST_UINT(kBasisA1, 8u)
SOFTGI_CONST_UINT(kBasisA, 16u)
SOFTGI_CONST_UINT(kBasisB, 80u)
SOFTGI_CONST_UINT(kBasisAsin, 144u)
SOFTGI_CONST_UINT(kBasisFloats, 152u)

// Replacement rules (shexp::ReplacementRule), as a specialization constant.
SOFTGI_CONST_UINT(kRuleOff, 0u)
SOFTGI_CONST_UINT(kRuleContinuous, 1u)
SOFTGI_CONST_UINT(kRuleClamped, 2u)
SOFTGI_CONST_UINT(kRulePrinted, 3u)
SOFTGI_CONST_UINT(kRuleInsideOnly, 4u)
// Exponential methods of the Vulkan exponentiate pass.
SOFTGI_CONST_UINT(kExpHyb, 0u)
SOFTGI_CONST_UINT(kExpOl, 1u)
SOFTGI_CONST_UINT(kExpPsStar, 2u)  // PS*-p: the factored series (eq. 22) of the scaled vector, then squarings
SOFTGI_CONST_UINT(kExpPs, 3u)      // PS-p: the plain product series (eq. 17), no DC isolation, no scaling
SOFTGI_CONST_UINT(kExpMaxDegree, 30u)  // the largest series degree p (the ps_degree parameter's range)
// Status words of the exponentiate pass.
SOFTGI_CONST_UINT(kExpStatusSquarings, 0u)
SOFTGI_CONST_UINT(kExpStatusBadInput, 1u)    // first receiver with a non-finite log coefficient + 1 (atomicMin of i + 1; 0xffffffff none)
SOFTGI_CONST_UINT(kExpStatusOverflow, 2u)    // first receiver whose result overflowed + 1 (same convention)
SOFTGI_CONST_UINT(kExpStatusDcOverflow, 3u)  // first receiver whose DC factor overflowed + 1
SOFTGI_CONST_UINT(kExpStatusLoopBudget, 4u)  // first receiver whose loops exceed the driver's limit + 1
SOFTGI_CONST_UINT(kExpStatusWords, 5u)

// accumulate_log bindings (set 0)
SOFTGI_CONST_UINT(kAccBindReceivers, 0u)     // float[6 * count]: px, py, pz, nx, ny, nz planes
SOFTGI_CONST_UINT(kAccBindReceiverList, 1u)  // uint per receiver: index of its blocker list
SOFTGI_CONST_UINT(kAccBindListRange, 2u)     // uvec2 per list: (first blocker, count)
SOFTGI_CONST_UINT(kAccBindBlockers, 3u)      // vec4 per blocker: centre, radius
SOFTGI_CONST_UINT(kAccBindWeights, 4u)       // per blocker: eq. 37 band weights, order rounded up to a multiple of 4 floats
SOFTGI_CONST_UINT(kAccBindTable, 5u)         // ZhTable::data: rows * 2 * order floats
SOFTGI_CONST_UINT(kAccBindBasis, 6u)         // basis recurrence constants (a uniform buffer; see sh_basis.glsl)
SOFTGI_CONST_UINT(kAccBindOut, 7u)           // float[count * order^2]

// exponentiate bindings (set 0)
SOFTGI_CONST_UINT(kExpBindIn, 0u)        // log vectors, float[count * n^2]
SOFTGI_CONST_UINT(kExpBindOut, 1u)       // visibility, float[count * n_out^2]
SOFTGI_CONST_UINT(kExpBindOl, 2u)        // OL tables: norm grid, a, b (floats)
// 3-6: unused (the squares and products are generated code, shaders/include/sh_exp.glsl)
SOFTGI_CONST_UINT(kExpBindStatus, 7u)    // uint[4]: squarings, products, non-finite receivers, overflow
SOFTGI_CONST_UINT(kExpBindSeries, 8u)    // PS*: 1/k! as float(1/double k!); PS: 1.0f/k (k = 0..degree)

// shade bindings (set 0)
SOFTGI_CONST_UINT(kShadeBindReceivers, 0u)
SOFTGI_CONST_UINT(kShadeBindVis, 1u)
SOFTGI_CONST_UINT(kShadeBindConsts, 2u)   // uniform block of kShadeConstFloats: L (3 n^2), hcoef (n^2), gwin (n^2)
SOFTGI_CONST_UINT(kShadeBindVis4, 3u)     // the visibility buffer again, as RGBA32F texels (n^2 a multiple of 4)
// 4: unused (the products are generated code, shaders/include/sh_plan_products.glsl)
SOFTGI_CONST_UINT(kShadeBindBasis, 5u)
SOFTGI_CONST_UINT(kShadeBindOut, 6u)      // vec4 per receiver (rgb, unused)
SOFTGI_CONST_UINT(kShadeBindTapPixel, 7u)    // gather: int per receiver, the display pixel whose taps it reads
SOFTGI_CONST_UINT(kShadeBindTapIndex, 8u)    // gather: ivec4 per display pixel, coarse samples (-1 unused, packed to the front)
SOFTGI_CONST_UINT(kShadeBindTapWeight, 9u)   // gather: vec4 per display pixel, their eq. 11 weights (paper 000)
SOFTGI_CONST_UINT(kShadeBindLightTable, 10u) // spherical lights: LightLobeTable psi (rows_theta x rows_f), then k (x order)
SOFTGI_CONST_UINT(kShadeBindLights, 11u)     // spherical lights: 2 vec4 per light (centre, radius; radiance, 0)
SOFTGI_CONST_UINT(kShadeBindStatus, 12u)     // uint: receivers whose shading was clamped at 0
SOFTGI_CONST_UINT(kShadeBindCoarseRow, 13u)  // gather with kShadeFlagCoarseRow: int per coarse sample, its row of the field
SOFTGI_CONST_UINT(kShadeBindPixelPosition, 14u)  // REC = kShadeRecPixels: vec4 per display pixel (position, depth)
SOFTGI_CONST_UINT(kShadeBindPixelNormal, 15u)    // REC = kShadeRecPixels: vec4 per display pixel (normal, depth)
// Where shade.comp reads a receiver's position and normal (specialisation constant REC).
SOFTGI_CONST_UINT(kShadeRecPlanes, 0u)  // six planes px, py, pz, nx, ny, nz of `count` receivers
SOFTGI_CONST_UINT(kShadeRecPixels, 1u)  // gather: the display G-buffer's planes at the receiver's pixel (tap_pixel)
// Where shade.comp reads a receiver's visibility g (specialisation constant VIS).
SOFTGI_CONST_UINT(kShadeVisNone, 0u)      // unshadowed: g = sqrt(4 pi) y_00
SOFTGI_CONST_UINT(kShadeVisReceiver, 1u)  // n^2 floats per receiver
SOFTGI_CONST_UINT(kShadeVisGather, 2u)    // interpolated from a coarse field with per-pixel taps (image_splat, eq. 11)
// shade.comp push-constant flags.
SOFTGI_CONST_UINT(kShadeFlagZeroNormalEmpty, 1u)  // a receiver with a zero normal (no surface) shades to 0
SOFTGI_CONST_UINT(kShadeFlagCoarseRow, 2u)        // gather: a tap's coarse sample reads field row coarse_row[sample]

#undef SOFTGI_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
