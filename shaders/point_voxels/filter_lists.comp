#version 450
// The visibility filter (paper 002 section 3.2, eq. 4) on bitsets: V'_p is the union of the lists
// V_q over the (2m + 1) x (2n + 1) window where delta_d delta_n = 1 (pixel p always; background
// pixels have no list and take none). One invocation per (pixel, run of WORDS bitset words): it
// decides each neighbour once and ORs the neighbour's words of its run, where one invocation per word
// decided every neighbour again for each word (the pixel records read lane by lane on llvmpipe).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
// Bitset words per invocation: the host sets min(words, kPvFilterWords), so that a pixel's words
// take one invocation on grids up to 32 * kPvFilterWords cells and the arrays below stay small.
layout(constant_id = 0) const uint WORDS = 16u;
layout(std430, set = 0, binding = kPvFiltBindPixels) readonly buffer Pixels { MarchPixel pixels[]; };
layout(std430, set = 0, binding = kPvFiltBindIn) readonly buffer In { uint bits_in[]; };
layout(std430, set = 0, binding = kPvFiltBindOut) writeonly buffer Out { uint bits_out[]; };
layout(std430, set = 0, binding = kPvFiltBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  uint first, end;   // (pixel, run) items of this dispatch: item = pixel * runs + run
  int width, height;
  uint words;
  int radius_x, radius_y;
  float depth_threshold, normal_threshold;
} pc;

void main() {
  const uint item = pc.first + gl_GlobalInvocationID.x;
  if (item >= pc.end) return;
  const uint runs = (pc.words + WORDS - 1u) / WORDS;
  const uint p = item / runs, w0 = (item % runs) * WORDS;
  const MarchPixel mp = pixels[p];
  uint acc[WORDS];
  [[unroll]] for (uint w = 0u; w < WORDS; ++w) acc[w] = 0u;
  if (mp.pos_hit.w != 0.0) {
    const int x = int(p % uint(pc.width)), y = int(p / uint(pc.width));
    const float zp = mp.normal_depth.w;
    for (int j = max(0, y - pc.radius_y); j <= min(pc.height - 1, y + pc.radius_y); ++j)
      for (int i = max(0, x - pc.radius_x); i <= min(pc.width - 1, x + pc.radius_x); ++i) {
        const uint q = uint(j) * uint(pc.width) + uint(i);
        if (q != p) {
          // same_surface (pv_core.cpp): delta_d delta_n of eq. 4.
          const MarchPixel mq = pixels[q];
          if (mq.pos_hit.w == 0.0) continue;
          if (!(abs(mq.normal_depth.w - zp) <= pc.depth_threshold * zp && dot(mp.normal_depth.xyz, mq.normal_depth.xyz) >= pc.normal_threshold))
            continue;
        }
        [[unroll]] for (uint w = 0u; w < WORDS; ++w)
          if (w0 + w < pc.words) acc[w] |= bits_in[q * pc.words + w0 + w];
      }
  }
  uint listed = 0u;
  [[unroll]] for (uint w = 0u; w < WORDS; ++w)
    if (w0 + w < pc.words) {
      bits_out[p * pc.words + w0 + w] = acc[w];
      listed += uint(bitCount(acc[w]));
    }
  if (listed != 0u) atomicAdd(status[kPvStatusCount], listed);
}
