#version 450
#extension GL_GOOGLE_include_directive : require
// G-buffer rasterisation, fragment stage: a visibility buffer, the object, its primitive and the
// rasterised barycentrics. Position, depth and normal follow from them in gbuffer_resolve.comp, once
// per pixel: here they would be computed for every fragment, also the ones a nearer surface hides
// and, on a SIMD rasteriser, for every lane of a block that a small triangle barely covers.
#include "gbuffer_shared.h"

layout(push_constant, std430) uniform GbDraw {
  int object;            // PosedScene::objects index
  uint first_triangle;   // the object's first triangle in the shared index buffer
  uint has_normals;      // 1: the object has one vertex normal per vertex
} draw;

layout(location = 0) in vec3 in_weights;
layout(location = 1) flat in uint in_triangle;

layout(location = kGbOutIds) out ivec2 out_ids;
layout(location = kGbOutBarycentric) out vec2 out_barycentric;

void main() {
  out_ids = ivec2(draw.object, int(in_triangle - draw.first_triangle));
  out_barycentric = in_weights.yz;
}
