// Constants of point-proxy voxels' compute shaders (shaders/point_voxels/*.comp, paper 002), shared by
// the C++ side (techniques/point_voxels/pv_vulkan.cpp) and GLSL: one declaration, included by both.
#ifndef SOFTGI_PV_SHARED_H
#define SOFTGI_PV_SHARED_H

#ifdef __cplusplus
#include <cstdint>
namespace softgi::gpu {
#define SOFTGI_PV_CONST_UINT(name, value) inline constexpr std::uint32_t name = value;
#else
#define SOFTGI_PV_CONST_UINT(name, value) const uint name = value;
#endif

// Workgroup size of every point_voxels shader but the scan (one invocation per proxy, ray, pixel,
// bitset word or cell), the scan's single workgroup, and the sort's: each of its invocations
// compares kPvSortPairs pairs per step, and a workgroup sorts or merges a block of
// 2 kPvSortGroup kPvSortPairs keys in shared memory (16 KiB).
SOFTGI_PV_CONST_UINT(kPvGroup, 64u)
SOFTGI_PV_CONST_UINT(kPvScanGroup, 256u)
SOFTGI_PV_CONST_UINT(kPvSortGroup, 256u)
SOFTGI_PV_CONST_UINT(kPvSortPairs, 4u)

// Every shader reads the grid at binding 0: vec4 (lo, disc radius), vec4 (cell size, patch area),
// vec4 (1 / cell size, 0), ivec4 (dims, cells), uvec4 (proxies, 0, 0, 0).
SOFTGI_PV_CONST_UINT(kPvBindGrid, 0u)

// Proxies, unsorted and sorted: struct { vec4 position; vec4 normal; vec4 albedo; uvec4 meta; },
// meta = (environment ray seed, sampling index, voxel key, 0).
// voxel_keys: key, histogram and the sort's (key, sampling index) pairs.
SOFTGI_PV_CONST_UINT(kPvKeyBindProxies, 1u)
SOFTGI_PV_CONST_UINT(kPvKeyBindCount, 2u)     // uint per cell (zeroed before)
SOFTGI_PV_CONST_UINT(kPvKeyBindPairs, 3u)     // uvec2 per proxy, padded to a power of two with (~0, ~0)
// voxel_scan: exclusive scan of the histogram (one workgroup).
SOFTGI_PV_CONST_UINT(kPvScanBindCount, 1u)
SOFTGI_PV_CONST_UINT(kPvScanBindStart, 2u)    // uint per cell + 1
SOFTGI_PV_CONST_UINT(kPvScanBindStatus, 3u)
// voxel_sort: the pairs in ascending order (a bitonic network, several dispatches).
SOFTGI_PV_CONST_UINT(kPvSortBindPairs, 1u)
// voxel_scatter: the proxies in the sorted pairs' order.
SOFTGI_PV_CONST_UINT(kPvScatBindIn, 1u)
SOFTGI_PV_CONST_UINT(kPvScatBindPairs, 2u)
SOFTGI_PV_CONST_UINT(kPvScatBindOut, 3u)

// march: one invocation per (source, ray): the first voxel whose discs the ray hits.
SOFTGI_PV_CONST_UINT(kPvMarchBindProxies, 1u)  // sorted proxies
SOFTGI_PV_CONST_UINT(kPvMarchBindStart, 2u)    // cell ranges
SOFTGI_PV_CONST_UINT(kPvMarchBindPixels, 3u)   // MarchPixel per marching pixel (sources = pixels)
SOFTGI_PV_CONST_UINT(kPvMarchBindSky, 4u)      // vec4 per sky SH coefficient (order 3: 9)
SOFTGI_PV_CONST_UINT(kPvMarchBindItems, 5u)    // struct { uvec4 state; vec4 radiance; } per (source, ray)
SOFTGI_PV_CONST_UINT(kPvMarchBindStatus, 6u)   // status words
SOFTGI_PV_CONST_UINT(kPvMarchBindDiscs, 7u)    // the sorted proxies again, as RGBA32F texels (4 per proxy) for the disc tests
SOFTGI_PV_CONST_UINT(kPvMarchBindSources, 8u)  // uint per source pixel: its index in the pixels (the hit pixels only)
// Sources of the march shader (specialisation constant 0).
SOFTGI_PV_CONST_UINT(kPvSourceProxies, 0u)
SOFTGI_PV_CONST_UINT(kPvSourcePixels, 1u)
// Item state: x phase (0 not started, 1 out of budget, to resume; 2 done), y DDA steps taken before
// the current cell, z next disc of the current cell, w the voxel hit (int bits; -1 none).
SOFTGI_PV_CONST_UINT(kPvPhaseNew, 0u)
SOFTGI_PV_CONST_UINT(kPvPhaseResume, 1u)
SOFTGI_PV_CONST_UINT(kPvPhaseDone, 2u)

// vpl_light: one invocation per sorted proxy: its radiance from the lights and the environment rays.
SOFTGI_PV_CONST_UINT(kPvLitBindProxies, 1u)
SOFTGI_PV_CONST_UINT(kPvLitBindItems, 2u)      // the proxies' environment rays (march items)
SOFTGI_PV_CONST_UINT(kPvLitBindLights, 3u)     // per local light: vec4 (centre, radius), vec4 (radiance, 0)
SOFTGI_PV_CONST_UINT(kPvLitBindCube, 4u)       // float: 6 size^2 depths per local light
SOFTGI_PV_CONST_UINT(kPvLitBindSun, 5u)        // float: the directional map's header (kPvSunHeader floats), then size^2 depths
SOFTGI_PV_CONST_UINT(kPvLitBindRadiance, 6u)   // vec4 per sorted proxy (out)
// vpl_finish: per cell, eqs. 2-3 summed over its VPLs in sorted order: 12 SH sums (coefficient-major,
// RGB), then the centroid (floats 12-14), 0.
SOFTGI_PV_CONST_UINT(kPvFinBindStart, 1u)
SOFTGI_PV_CONST_UINT(kPvFinBindSh, 2u)
SOFTGI_PV_CONST_UINT(kPvFinBindProxies, 3u)
SOFTGI_PV_CONST_UINT(kPvFinBindRadiance, 4u)
// The directional map's header: dir.xyz, u.xyz, v.xyz, lo.xy, extent.xy, size.
SOFTGI_PV_CONST_UINT(kPvSunHeader, 16u)
SOFTGI_PV_CONST_UINT(kPvVoxelFloats, 16u)      // floats per cell of the SH buffer

// march_lists: per marching pixel that sees a surface, its rays' voxels as a bitset, the escaped
// rays' sky light (the others keep the zeroed bitsets and fields).
SOFTGI_PV_CONST_UINT(kPvListBindItems, 2u)
SOFTGI_PV_CONST_UINT(kPvListBindBits, 3u)      // uint words per pixel (zeroed before)
SOFTGI_PV_CONST_UINT(kPvListBindFields, 4u)    // vec4 per pixel: sky irradiance, escaped fraction
SOFTGI_PV_CONST_UINT(kPvListBindStatus, 5u)
SOFTGI_PV_CONST_UINT(kPvListBindSources, 6u)   // as kPvMarchBindSources

// filter_lists (per pixel and bitset word) and filter_fields (per pixel): eq. 4.
SOFTGI_PV_CONST_UINT(kPvFilterWords, 32u)     // filter_lists: most bitset words one invocation ORs
SOFTGI_PV_CONST_UINT(kPvFiltBindPixels, 1u)
SOFTGI_PV_CONST_UINT(kPvFiltBindIn, 2u)
SOFTGI_PV_CONST_UINT(kPvFiltBindOut, 3u)
SOFTGI_PV_CONST_UINT(kPvFiltBindStatus, 4u)

// gather: per gathering pixel, eqs. 5-6 over the union of its four neighbours' filtered bitsets.
SOFTGI_PV_CONST_UINT(kPvGathBindProxies, 1u)
SOFTGI_PV_CONST_UINT(kPvGathBindRadiance, 2u)
SOFTGI_PV_CONST_UINT(kPvGathBindStart, 3u)
SOFTGI_PV_CONST_UINT(kPvGathBindSh, 4u)
SOFTGI_PV_CONST_UINT(kPvGathBindMarch, 5u)     // MarchPixel per marching pixel
SOFTGI_PV_CONST_UINT(kPvGathBindBits, 6u)      // filtered bitsets
SOFTGI_PV_CONST_UINT(kPvGathBindReceivers, 7u) // per gathering pixel: vec4 (position, depth), vec4 (normal, glossiness),
                                               // vec4 (reflection vector, ns), vec4 (eq. 7 sigma, hit, lobe norm, 0)
SOFTGI_PV_CONST_UINT(kPvGathBindOut, 8u)       // vec4 irradiance, glossy, weighted (w: eq. 7 used) per pixel
SOFTGI_PV_CONST_UINT(kPvGathBindState, 9u)     // per pixel: uvec4 (phase, next voxel, next VPL, voxels gathered),
                                               // vec4 (the current voxel's VPL irradiance sum so far)
SOFTGI_PV_CONST_UINT(kPvGathBindStatus, 10u)
SOFTGI_PV_CONST_UINT(kPvGathBindSources, 11u)  // uint per gathering pixel that sees a surface: its index

// depth_raster.vert (light_maps): the posed triangles' corners, vec4 each, 3 per triangle.
SOFTGI_PV_CONST_UINT(kPvRasterBindCorners, 0u)
SOFTGI_PV_CONST_UINT(kPvRasterCube, 0u)    // push constant mode: a cube map face
SOFTGI_PV_CONST_UINT(kPvRasterOrtho, 1u)   // the sun's directional map
// depth_resolve.comp: the depth attachments' values (copied to a buffer) to the CPU maps' depths.
SOFTGI_PV_CONST_UINT(kPvResolveBindRaw, 0u)
SOFTGI_PV_CONST_UINT(kPvResolveBindOut, 1u)

// Status words (one buffer per pass, reset before it).
SOFTGI_PV_CONST_UINT(kPvStatusUnfinished, 0u)  // invocations that ran out of loop budget this dispatch
SOFTGI_PV_CONST_UINT(kPvStatusCount, 1u)       // voxel_scan: occupied cells; march_lists / filter_lists: list entries; gather: voxels gathered
SOFTGI_PV_CONST_UINT(kPvStatusUnmatched, 2u)   // gather: pixels with no neighbour on their surface
SOFTGI_PV_CONST_UINT(kPvStatusLargest, 3u)     // voxel_scan: the most proxies in one cell
SOFTGI_PV_CONST_UINT(kPvStatusWords, 4u)

#undef SOFTGI_PV_CONST_UINT
#ifdef __cplusplus
}  // namespace softgi::gpu
#endif

#endif
