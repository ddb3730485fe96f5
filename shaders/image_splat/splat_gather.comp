#version 450
// image_splat's shadow splats, last step: the blended attachments (copied to `raw`, one plane of
// vec4 per attachment) read out in receiver order, n^2 floats per receiver, the layout of the log
// occlusion accumulate_log.comp writes.
#extension GL_GOOGLE_include_directive : require
#include "image_splat_splat_shared.h"

layout(local_size_x = kSplatGatherGroup) in;
layout(set = 0, binding = kSplatGatherBindRaw) uniform samplerBuffer raw;
layout(set = 0, binding = kSplatGatherBindPixel) uniform isamplerBuffer pixel;
layout(std430, set = 0, binding = kSplatGatherBindOut) writeonly buffer Out { float outv[]; };
layout(push_constant) uniform Push {
  uint first, end;  // receivers of this dispatch
  uint n2;          // coefficients per receiver
  uint pixels;      // of the buffer (one attachment's plane)
} pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint p = uint(texelFetch(pixel, int(i)).x);
  for (uint c = 0; c < pc.n2; ++c) outv[i * pc.n2 + c] = texelFetch(raw, int((c / 4u) * pc.pixels + p))[c % 4u];
}
