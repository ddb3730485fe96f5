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

layout(set = 0, binding = kGbBindPositions, std430) readonly buffer GbPositions { float positions[]; };
layout(set = 0, binding = kGbBindNormals, std430) readonly buffer GbNormals { float normals[]; };
layout(set = 0, binding = kGbBindIndices, std430) readonly buffer GbIndices { uint indices[]; };

vec3 fetch_position(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }
vec3 fetch_normal(uint v) { return vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]); }
