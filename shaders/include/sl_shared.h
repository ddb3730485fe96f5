// Constants of the spherical-lights shaders (shaders/spherical_lights/*.comp, paper 001), shared by
// the C++ side (techniques/spherical_lights/sl_vulkan.cpp) and GLSL.
#ifndef SOFTGI_SL_SHARED_H
#define SOFTGI_SL_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_SL_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_SL_CONST_UINT(name, value) const uint name = value;
#endif

SOFTGI_SL_CONST_UINT(kSlIntensityGroup, 64u)  // invocations (SL x channel) per workgroup
SOFTGI_SL_CONST_UINT(kSlIndirectGroup, 64u)   // receivers per workgroup
// The most SLs accumulate_indirect.comp orders per receiver (its per-invocation key arrays are this
// long); the host refuses more.
SOFTGI_SL_CONST_UINT(kSlMaxLights, 512u)

// intensity.comp bindings (set 0): section 5.2, eqs. 10-11.
SOFTGI_SL_CONST_UINT(kSlIntBindRadiance, 0u)  // float[3 * samples]: L_p per sample point (rgb)
SOFTGI_SL_CONST_UINT(kSlIntBindRanges, 1u)    // uint[SLs + 1]: each SL's first sample point
SOFTGI_SL_CONST_UINT(kSlIntBindBasis, 2u)     // float[samples * n^2]: (4 pi/N) Y_j per sample point (eq. 10)
SOFTGI_SL_CONST_UINT(kSlIntBindAlbedo, 3u)    // float[SLs * 3 * n^2]: c_S, channel-major per SL
// 4, 5: unused (the products are generated code, shaders/include/sh_plan_products.glsl)
SOFTGI_SL_CONST_UINT(kSlIntBindOut, 6u)       // float[SLs * 3 * n^2]: L^c_S (eq. 11), channel-major per SL

// accumulate_indirect.comp bindings (set 0): section 6. The SLs a receiver sums are the entries of
// its cluster's list (every leaf, or a hierarchy cut); the per-SL arrays below are per list entry.
SOFTGI_SL_CONST_UINT(kSlIndBindReceivers, 0u)   // float[6 * count]: px, py, pz, nx, ny, nz planes
SOFTGI_SL_CONST_UINT(kSlIndBindSpheres, 1u)     // vec4 per SL: posed centre, radius
SOFTGI_SL_CONST_UINT(kSlIndBindRotation, 2u)    // 3 vec4 per SL: the columns of its rotation (rest -> world)
SOFTGI_SL_CONST_UINT(kSlIndBindObject, 3u)      // uint per SL: its object
SOFTGI_SL_CONST_UINT(kSlIndBindObjCentre, 4u)   // vec4 per object: the mean of its SLs' centres
SOFTGI_SL_CONST_UINT(kSlIndBindInterBegin, 5u)  // uint[SLs + 1]: CSR offsets of the intersecting lists
SOFTGI_SL_CONST_UINT(kSlIndBindInterList, 6u)   // uint: same-object intersecting SLs (section 6.2)
SOFTGI_SL_CONST_UINT(kSlIndBindIntensity, 7u)   // float[SLs * 3 * n^2]: L^c_S
SOFTGI_SL_CONST_UINT(kSlIndBindLogTable, 8u)    // ZhTable::data of the cap log table
SOFTGI_SL_CONST_UINT(kSlIndBindWeight, 9u)      // WeightTable::w: rows x n (w_theta, eqs. 16-17)
SOFTGI_SL_CONST_UINT(kSlIndBindConsts, 10u)     // float[2 n]: H(N) band factors, then sqrt(4 pi/(2l+1))
SOFTGI_SL_CONST_UINT(kSlIndBindBasis, 11u)      // shexp basis recurrence constants (asin included)
SOFTGI_SL_CONST_UINT(kSlIndBindOl, 12u)         // OL table: norm grid, a, b
// 13, 14: unused (the squares are generated code, shaders/include/sh_exp.glsl)
SOFTGI_SL_CONST_UINT(kSlIndBindOut, 15u)        // vec4 per receiver: E/pi (rgb), unused
SOFTGI_SL_CONST_UINT(kSlIndBindStatus, 16u)     // uint[kSlStatusWords]
SOFTGI_SL_CONST_UINT(kSlIndBindEntrySl, 17u)    // uint per list entry: its SL (row of the intensities)
SOFTGI_SL_CONST_UINT(kSlIndBindRatio, 18u)      // vec4 per list entry: the reflection ratio t (eq. 25), rgb
SOFTGI_SL_CONST_UINT(kSlIndBindRList, 19u)      // uint per receiver: its cluster's list (section 7.3)
SOFTGI_SL_CONST_UINT(kSlIndBindLists, 20u)      // uvec2 per list: first entry, entries
SOFTGI_SL_CONST_UINT(kSlIndBindState, 21u)      // float[(n^2 + 4) * count]: per receiver the pass state
                                                // (prefix sum of G, the sum so far (rgb), last SL)
// accumulate_indirect.comp's per-receiver state: the last SL summed (the bits of a uint in the state's
// last float), none yet, or the receiver done.
SOFTGI_SL_CONST_UINT(kSlStateNone, 0xffffffffu)
SOFTGI_SL_CONST_UINT(kSlStateDone, 0xfffffffeu)

// accumulate_indirect.comp's blocking order (section 7.2; spherical_lights::Blocking).
SOFTGI_SL_CONST_UINT(kSlPerSphere, 0u)
SOFTGI_SL_CONST_UINT(kSlPerObject, 1u)
// Status words: counters, and the first failing receiver + 1 (atomicMin; 0xffffffff none).
SOFTGI_SL_CONST_UINT(kSlStatusPairs, 0u)       // SL-receiver pairs shaded
SOFTGI_SL_CONST_UINT(kSlStatusEliminated, 1u)  // pairs the replacement rules removed
SOFTGI_SL_CONST_UINT(kSlStatusClamped, 2u)     // Vbar below 0 set to 0
SOFTGI_SL_CONST_UINT(kSlStatusBadInput, 3u)    // a non-finite log coefficient
SOFTGI_SL_CONST_UINT(kSlStatusDcOverflow, 4u)  // a DC factor overflowed
SOFTGI_SL_CONST_UINT(kSlStatusOverflow, 5u)    // an exponential overflowed
SOFTGI_SL_CONST_UINT(kSlStatusUnfinished, 6u)  // receivers that stopped at the pass's loop budget
SOFTGI_SL_CONST_UINT(kSlStatusBudget, 7u)      // one SL's work alone exceeds the loop budget
SOFTGI_SL_CONST_UINT(kSlStatusWords, 8u)

#undef SOFTGI_SL_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
