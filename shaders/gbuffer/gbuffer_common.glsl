// Resources of the G-buffer rasterisation shaders (gbuffer_raster.vert / .frag); the C++ mirror of
// GbFrame is in backends/vulkan/gbuffer_raster.cpp.
#include "gbuffer_shared.h"

layout(set = 0, binding = kGbBindFrame, std140) uniform GbFrame {
  mat4 clip_from_world;  // see gbuffer_raster.cpp: receiver pixel centres on display points
  vec4 eye;              // xyz: camera position e
  vec4 forward;          // xyz: unit view direction E (render::PinholeCamera::forward)
  vec4 right;            // xyz
  vec4 up;               // xyz
  vec4 image;            // display width, display height, scale s, tan_half_fov_y
  vec4 image2;           // aspect (width / height), unused x3
} frame;

// Vertex arrays through texel buffers: a SIMD device fetches texels for all lanes at once, where it
// reads a storage buffer lane by lane with a bounds check per component (llvmpipe).
layout(set = 0, binding = kGbBindPositions) uniform samplerBuffer positions;
layout(set = 0, binding = kGbBindNormals) uniform samplerBuffer normals;
layout(set = 0, binding = kGbBindIndices) uniform usamplerBuffer indices;

vec3 fetch3(samplerBuffer b, uint v) {
  const int k = int(3u * v);
  return vec3(texelFetch(b, k).x, texelFetch(b, k + 1).x, texelFetch(b, k + 2).x);
}
vec3 fetch_position(uint v) { return fetch3(positions, v); }
vec3 fetch_normal(uint v) { return fetch3(normals, v); }
uint fetch_index(uint k) { return texelFetch(indices, int(k)).x; }
