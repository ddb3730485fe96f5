#version 450
// Test shader for SPIR-V reflection: two descriptor sets, a uniform buffer, a storage image, a
// combined image sampler, an array of storage buffers, and a push-constant block with a vec4 at
// offset 16 (size 32).
layout(local_size_x = 8, local_size_y = 4, local_size_z = 2) in;
layout(std140, set = 0, binding = 0) uniform U { vec4 scale; } u;
layout(std430, set = 0, binding = 2) buffer Out { float v[]; } outs[3];
layout(set = 1, binding = 0, rgba32f) uniform writeonly image2D img;
layout(set = 1, binding = 3) uniform sampler2D tex;
layout(push_constant) uniform Push {
  uint n;
  vec4 tint;
} pc;

void main() {
  const uint i = gl_GlobalInvocationID.x;
  const vec4 t = texture(tex, vec2(0.5));
  if (i < pc.n) outs[i % 3].v[i] = u.scale.x * pc.tint.y + t.x;
  imageStore(img, ivec2(gl_GlobalInvocationID.xy), pc.tint);
}
