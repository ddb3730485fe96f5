#version 450
// The proxies in eq. 1's sorted order: slot s takes the proxy of the s-th sorted (key, sampling index)
// pair (voxel_sort), so that each cell's range holds its proxies in sampling order, as the CPU's
// stable sort does.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvScatBindIn) readonly buffer In { Proxy uprox[]; };
layout(std430, set = 0, binding = kPvScatBindPairs) readonly buffer Pairs { uvec2 pairs[]; };
layout(std430, set = 0, binding = kPvScatBindOut) writeonly buffer Out { Proxy sprox[]; };
layout(push_constant) uniform Push { uint first, end; } pc;

void main() {
  const uint s = pc.first + gl_GlobalInvocationID.x;
  if (s >= pc.end) return;
  sprox[s] = uprox[pairs[s].y];
}
