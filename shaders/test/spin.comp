#version 450
// Test shader: a long-running loop (the fence-timeout test). The result is written so that the
// loop cannot be removed.
layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) buffer Out { float v[]; };
layout(push_constant) uniform Push { uint iterations; } pc;

void main() {
  float x = float(gl_GlobalInvocationID.x) * 1e-3;
  for (uint k = 0u; k < pc.iterations; ++k) x = fract(x * 1.0001 + 0.1234);
  v[gl_GlobalInvocationID.x] = x;
}
