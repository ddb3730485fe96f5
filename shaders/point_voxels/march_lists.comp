#version 450
// Each marching pixel's list of visible voxels (paper 002 section 3.1, V_p), as a bitset over the
// grid's cells (sorted and free of duplicates by construction), from its rays' first hits; the
// escaped rays' sky light as irradiance pi / rays sum L_k and the escaped fraction (pass_march).
// One invocation per source pixel of the batch (the marching pixels that see a surface).
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvListBindItems) readonly buffer Items { MarchItem items[]; };
layout(std430, set = 0, binding = kPvListBindBits) buffer Bits { uint bits[]; };
layout(std430, set = 0, binding = kPvListBindFields) writeonly buffer Fields { vec4 fields[]; };
layout(std430, set = 0, binding = kPvListBindStatus) buffer Status { uint status[]; };
layout(std430, set = 0, binding = kPvListBindSources) readonly buffer Sources { uint sources[]; };
layout(push_constant) uniform Push {
  uint first, end;   // source pixels of this batch
  uint rays;
  uint words;        // bitset words per pixel
  float sky_scale;   // pi / rays
} pc;

void main() {
  const uint src = pc.first + gl_GlobalInvocationID.x;
  if (src >= pc.end) return;
  const uint p = sources[src];
  vec3 e = vec3(0.0);
  uint escaped = 0u, listed = 0u;
  const uint base = (src - pc.first) * pc.rays;
  for (uint k = 0u; k < pc.rays; ++k) {
    const int v = int(items[base + k].state.w);
    if (v >= 0) {
      const uint w = p * pc.words + uint(v) / 32u, bit = 1u << (uint(v) % 32u);
      if ((bits[w] & bit) == 0u) {
        bits[w] |= bit;
        ++listed;
      }
    } else {
      ++escaped;
      e += items[base + k].radiance.xyz;
    }
  }
  fields[p] = vec4(e * pc.sky_scale, float(escaped) / float(pc.rays));
  if (listed > 0u) atomicAdd(status[kPvStatusCount], listed);
}
