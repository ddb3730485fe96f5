#version 450
// image_splat's binning (paper 000 section 4.1) as a compute pass: per receiver tile, the proxies
// whose sphere of influence reaches the tile's box, in proxy order, as bin_proxies
// (techniques/image_splat/image_splat_core.cpp) lists them on the host. One invocation per tile
// walks the proxies in order: the lists, and every sum over them, are the host's, with no scan and
// no workgroup barrier (a workgroup per tile with an in-order compaction by prefix sums measured
// several times slower on llvmpipe, where barriers are costly). Two modes: count (how many reach
// each tile, for the host to lay the lists out) and scatter (write them).
#extension GL_GOOGLE_include_directive : require
#include "image_splat_binning_shared.h"

layout(local_size_x = kBinGroup) in;

layout(set = 0, binding = kBinBindTiles) uniform samplerBuffer tiles;
layout(set = 0, binding = kBinBindTest) uniform samplerBuffer test;
layout(set = 0, binding = kBinBindSrcA) uniform samplerBuffer src_a;
layout(set = 0, binding = kBinBindSrcB) uniform samplerBuffer src_b;
layout(set = 0, binding = kBinBindCount, std430) buffer Count { uint count[]; };
layout(set = 0, binding = kBinBindRanges) uniform usamplerBuffer ranges;
layout(set = 0, binding = kBinBindDstA, std430) writeonly buffer DstA { vec4 dst_a[]; };
layout(set = 0, binding = kBinBindDstB, std430) writeonly buffer DstB { vec4 dst_b[]; };
layout(set = 0, binding = kBinBindIndex, std430) writeonly buffer Index { uint dst_index[]; };
layout(push_constant) uniform Push {
  uint mode;        // kBinCount or kBinScatter
  uint tile_first;  // tiles [tile_first, tile_end) in this dispatch (dispatched in chunks of the
  uint tile_end;    // group-count limit)
  uint first;       // proxies [first, end) in this dispatch (a driver's loop-iteration limit caps one
  uint end;         // invocation's loop; count[] carries each tile's total from chunk to chunk)
  uint payload;     // vec4s of src_b / dst_b per proxy, <= kBinMaxPayload
} pc;

// sphere_meets_box of image_splat_core.cpp, operation for operation: the clamp, the difference, the
// squared length summed x, y then z, the squared radius; `precise` keeps a driver from fusing them,
// so that a proxy on the boundary falls on the same side as on the host. An infinite radius (no
// sphere of influence) reaches every tile.
bool meets(vec4 s, vec3 lo, vec3 hi) {
  if (isinf(s.w)) return true;
  precise vec3 d = s.xyz - clamp(s.xyz, lo, hi);
  precise float dd = d.x * d.x + d.y * d.y;
  precise float d2 = dd + d.z * d.z;
  precise float r2 = s.w * s.w;
  return d2 <= r2;
}

void main() {
  const uint tile = pc.tile_first + gl_GlobalInvocationID.x;
  if (tile >= pc.tile_end) return;
  const vec3 lo = texelFetch(tiles, int(2u * tile)).xyz;
  const vec3 hi = texelFetch(tiles, int(2u * tile + 1u)).xyz;
  if (pc.mode == kBinCount) {
    uint n = 0u;
    for (uint p = pc.first; p < pc.end; ++p)
      if (meets(texelFetch(test, int(p)), lo, hi)) ++n;
    count[tile] += n;
    return;
  }
  const uint first = texelFetch(ranges, int(tile)).x;
  uint at = first + count[tile];
  for (uint p = pc.first; p < pc.end; ++p) {
    if (!meets(texelFetch(test, int(p)), lo, hi)) continue;
    dst_a[at] = texelFetch(src_a, int(p));
    for (uint q = 0u; q < pc.payload; ++q) dst_b[at * pc.payload + q] = texelFetch(src_b, int(p * pc.payload + q));
    dst_index[at] = p;
    ++at;
  }
  count[tile] = at - first;
}
