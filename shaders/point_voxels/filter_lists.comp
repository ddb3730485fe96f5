#version 450
// The visibility filter (paper 002 section 3.2, eq. 4) on bitsets: V'_p is the union of the lists
// V_q over the (2m + 1) x (2n + 1) window where delta_d delta_n = 1 (pixel p always; background
// pixels have no list and take none). One invocation per (pixel, bitset word), so that a word is
// the OR of at most (2m + 1)(2n + 1) words.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvFiltBindPixels) readonly buffer Pixels { MarchPixel pixels[]; };
layout(std430, set = 0, binding = kPvFiltBindIn) readonly buffer In { uint bits_in[]; };
layout(std430, set = 0, binding = kPvFiltBindOut) writeonly buffer Out { uint bits_out[]; };
layout(std430, set = 0, binding = kPvFiltBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  uint first, end;   // (pixel, word) items of this dispatch: item = pixel * words + word
  int width, height;
  uint words;
  int radius_x, radius_y;
  float depth_threshold, normal_threshold;
} pc;

void main() {
  const uint item = pc.first + gl_GlobalInvocationID.x;
  if (item >= pc.end) return;
  const uint p = item / pc.words, word = item % pc.words;
  const MarchPixel mp = pixels[p];
  if (mp.pos_hit.w == 0.0) {
    bits_out[item] = 0u;
    return;
  }
  const int x = int(p % uint(pc.width)), y = int(p / uint(pc.width));
  const float zp = mp.normal_depth.w;
  uint acc = 0u;
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
      acc |= bits_in[q * pc.words + word];
    }
  bits_out[item] = acc;
  if (acc != 0u) atomicAdd(status[kPvStatusCount], bitCount(acc));
}
