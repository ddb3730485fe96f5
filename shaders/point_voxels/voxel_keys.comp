#version 450
// Eq. 1 (paper 002 section 3.1): each proxy's voxel key H(v), the count of proxies per voxel (the
// histogram the scan turns into cell ranges) and the pair (key, sampling index) that voxel_sort
// orders. One invocation per proxy, in sampling order.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvKeyBindProxies) buffer Proxies { Proxy uprox[]; };
layout(std430, set = 0, binding = kPvKeyBindCount) buffer Count { uint count[]; };
layout(std430, set = 0, binding = kPvKeyBindPairs) writeonly buffer Pairs { uvec2 pairs[]; };
layout(push_constant) uniform Push { uint first, end; } pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint key = pv_hash(pv_cell_of(uprox[i].position.xyz));
  uprox[i].meta.z = key;
  pairs[i] = uvec2(key, i);
  atomicAdd(count[key], 1u);
}
