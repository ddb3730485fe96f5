#version 450
// One column of a row-major field a GPU pass left on the device: out[i] = in[i * stride + column]
// (image_splat's normalize_indirect reads O_p's DC coefficient of every receiver this way, and the
// rest of O_p stays on the device). One invocation per row.
#extension GL_GOOGLE_include_directive : require
#include "softgi_shared.h"

layout(local_size_x = kShadeGroup) in;
layout(std430, set = 0, binding = 0) readonly buffer In { float inv[]; };
layout(std430, set = 0, binding = 1) writeonly buffer Out { float outv[]; };
layout(push_constant) uniform Push {
  uint first, end;  // rows of this dispatch
  uint stride, column;
} pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  outv[i] = inv[i * pc.stride + pc.column];
}
