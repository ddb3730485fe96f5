#version 450
// out[p] = sum_k weight[p][k] in[index[p][k]] per channel (upsample.cpp upsample_apply): the eq. 11
// interpolation of a coarse field to display resolution, one invocation per display pixel with a
// tap (the host lists them, and leaves the others untouched), its values written in list order.
#extension GL_GOOGLE_include_directive : require
#include "upsample_shared.h"

layout(constant_id = 0) const uint CHANNELS = 3;
layout(local_size_x = kUpsampleGroupX * kUpsampleGroupY) in;

// Read through texel buffers (Bind::texels_at says why).
layout(set = 0, binding = kApBindIndex) uniform isamplerBuffer index;
layout(set = 0, binding = kApBindWeight) uniform samplerBuffer weight;
layout(set = 0, binding = kApBindIn) uniform samplerBuffer inv;
layout(set = 0, binding = kApBindOut, r32f) uniform writeonly imageBuffer outv;
layout(set = 0, binding = kApBindList) uniform usamplerBuffer list;
layout(push_constant) uniform Push {
  uint first, end;  // listed pixels of this dispatch
} pc;

void main() {
  const uint j = pc.first + gl_GlobalInvocationID.x;
  if (j >= pc.end) return;
  const uint p = texelFetch(list, int(j)).x;
  const ivec4 idx = texelFetch(index, int(p));
  const vec4 w = texelFetch(weight, int(p));
  for (uint c = 0; c < CHANNELS; ++c) {
    float acc = 0.0;
    for (int k = 0; k < 4 && idx[k] >= 0; ++k) acc += w[k] * texelFetch(inv, int(uint(idx[k]) * CHANNELS + c)).x;
    imageStore(outv, int(j * CHANNELS + c), vec4(acc));
  }
}
