#version 450
// The depth attachments' values to the depths of the CPU's maps (pv_core.cpp): a cube face's
// reverse-Z depth near / z back to z, the directional map's (z_hi + p . dir) / (z_hi - z_lo) back to
// -p . dir; +inf where nothing was drawn (both cleared to 0). One invocation per texel.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvResolveBindRaw) readonly buffer Raw { float raw[]; };
layout(std430, set = 0, binding = kPvResolveBindOut) writeonly buffer Out { float depth[]; };
layout(push_constant) uniform Push {
  uint first, end;
  uint mode;       // kPvRasterCube or kPvRasterOrtho
  uint out_offset; // first texel of the map in `depth`
  float near;      // cube
  float z_lo, z_range;  // ortho: depth = z_lo + d z_range
} pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const float d = raw[i];
  const float inf = uintBitsToFloat(0x7f800000u);
  if (pc.mode == kPvRasterCube) depth[pc.out_offset + i] = d > 0.0 ? pc.near / d : inf;
  else depth[pc.out_offset + i] = d > 0.0 ? pc.z_lo + d * pc.z_range : inf;
}
