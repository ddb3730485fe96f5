#version 450
// Each voxel's position: the centroid of its VPLs (paper 002 section 3.3), from the sums vpl_light
// added (accumulate_voxel_sh). One invocation per cell.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvFinBindStart) readonly buffer Start { uint cell_start[]; };
layout(std430, set = 0, binding = kPvFinBindSh) buffer Sh { uint vsh[]; };
layout(push_constant) uniform Push { uint first, end; } pc;

void main() {
  const uint k = pc.first + gl_GlobalInvocationID.x;
  if (k >= pc.end) return;
  const uint n = cell_start[k + 1u] - cell_start[k];
  for (uint c = 0u; c < 3u; ++c) {
    const uint w = k * kPvVoxelFloats + 12u + c;
    vsh[w] = floatBitsToUint(n > 0u ? uintBitsToFloat(vsh[w]) / float(n) : 0.0);
  }
}
