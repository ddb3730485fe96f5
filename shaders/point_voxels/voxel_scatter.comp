#version 450
// The proxies into their cell's range (the sort by eq. 1's key): each takes the next free slot of
// its cell. The order within a cell is the order the atomics grant slots in, not the sampling order
// (the CPU's sort is stable): nothing downstream depends on it but the order of float sums.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvScatBindIn) readonly buffer In { Proxy uprox[]; };
layout(std430, set = 0, binding = kPvScatBindCursor) buffer Cursor { uint cursor[]; };
layout(std430, set = 0, binding = kPvScatBindOut) writeonly buffer Out { Proxy sprox[]; };
layout(push_constant) uniform Push { uint first, end; } pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const Proxy p = uprox[i];
  sprox[atomicAdd(cursor[p.meta.z], 1u)] = p;
}
