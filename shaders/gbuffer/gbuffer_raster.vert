#version 450
#extension GL_GOOGLE_include_directive : require
// G-buffer rasterisation, vertex stage. One non-indexed draw per posed object covering its
// triangles [first, first + count) of the shared index buffer: vertex k of the draw is corner k % 3
// of triangle k / 3, so the corners keep the mesh's order (tri.x, tri.y, tri.z) and the
// per-corner weights (1,0,0), (0,1,0), (0,0,1), interpolated perspective-correctly by the
// rasteriser, are the CPU's barycentrics (b0, b1, b2) of those corners at the pixel centre.
#include "gbuffer_common.glsl"

layout(location = 0) out vec3 out_weights;
// The triangle's index in the shared index buffer, flat from the provoking vertex (all three
// corners carry the same value). Used instead of gl_PrimitiveID, which needs the geometryShader
// device feature in a fragment shader.
layout(location = 1) flat out uint out_triangle;

void main() {
  const uint k = uint(gl_VertexIndex);  // includes firstVertex = 3 * first triangle of the object
  const uint corner = k % 3u;
  gl_Position = frame.clip_from_world * vec4(fetch_position(fetch_index(k)), 1.0);
  out_weights = vec3(corner == 0u ? 1.0 : 0.0, corner == 1u ? 1.0 : 0.0, corner == 2u ? 1.0 : 0.0);
  out_triangle = k / 3u;
}
