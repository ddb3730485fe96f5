#version 450
// Test shader of the Vulkan infrastructure (tests/vulkan): y = a x + y with x read through a
// uniform texel buffer (samplerBuffer) and y through a storage texel buffer (imageBuffer).
layout(local_size_x = 64) in;
layout(set = 0, binding = 0) uniform samplerBuffer x;
layout(set = 0, binding = 1, r32f) uniform imageBuffer y;
layout(push_constant) uniform Push {
  uint n;
  float a;
} pc;

void main() {
  const int i = int(gl_GlobalInvocationID.x);
  if (i < int(pc.n)) imageStore(y, i, vec4(pc.a * texelFetch(x, i).x + imageLoad(y, i).x));
}
