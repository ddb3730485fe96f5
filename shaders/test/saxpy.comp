#version 450
// Test shader of the Vulkan infrastructure (tests/vulkan): y = a x + y, with push constants and
// two storage buffers whose layout comes from reflection.
#extension GL_GOOGLE_include_directive : require
#include "softgi_shared.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) readonly buffer X { float x[]; };
layout(std430, set = 0, binding = 1) buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint n;
  float a;
} pc;

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i < pc.n) y[i] = pc.a * x[i] + y[i];
}
