#version 450
#extension GL_GOOGLE_include_directive : require
// G-buffer rasterisation, fragment stage: the CPU G-buffer's per-hit rules
// (backends/cpu/gbuffer_embree.cpp, shade_hit) applied to the rasterised barycentrics, with the
// triangle's corners fetched from the same posed vertex arrays, so that both backends compute
// position, normal and depth with the same arithmetic from (object, primitive, b1, b2).
#include "gbuffer_common.glsl"

layout(push_constant, std430) uniform GbDraw {
  int object;            // PosedScene::objects index
  uint first_triangle;   // the object's first triangle in the shared index buffer
  uint has_normals;      // 1: the object has one vertex normal per vertex
} draw;

layout(location = 0) in vec3 in_weights;
layout(location = 1) flat in uint in_triangle;

layout(location = kGbOutPositionDepth) out vec4 out_position_depth;
layout(location = kGbOutNormal) out vec4 out_normal;
layout(location = kGbOutIds) out ivec2 out_ids;
layout(location = kGbOutBarycentric) out vec2 out_barycentric;

void main() {
  const float u = in_weights.y, v = in_weights.z, w = 1.0 - u - v;
  const uint t = in_triangle;
  const uint i0 = indices[3u * t], i1 = indices[3u * t + 1u], i2 = indices[3u * t + 2u];
  const vec3 p0 = fetch_position(i0), p1 = fetch_position(i1), p2 = fetch_position(i2);
  const vec3 p = w * p0 + u * p1 + v * p2;

  // The camera ray of this pixel: render::PinholeCamera::direction at display point
  // ((x + 0.5) s, (y + 0.5) s); gl_FragCoord.xy is the pixel centre (x + 0.5, y + 0.5).
  const float W = frame.image.x, H = frame.image.y, s = frame.image.z, tan_half = frame.image.w;
  const float px = gl_FragCoord.x * s, py = gl_FragCoord.y * s;
  const float sx = (2.0 * px / W - 1.0) * tan_half * frame.image2.x;
  const float sy = (1.0 - 2.0 * py / H) * tan_half;
  const vec3 dir = normalize(frame.forward.xyz + sx * frame.right.xyz + sy * frame.up.xyz);

  // Geometric normal turned against the ray (two-sided surfaces); the interpolated vertex normal,
  // normalised and turned to the geometric normal's side, unless missing or degenerate.
  vec3 ng = cross(p1 - p0, p2 - p0);
  const float len = length(ng);
  ng = len > 0.0 ? ng / len : -dir;
  if (dot(ng, dir) > 0.0) ng = -ng;
  vec3 ns = ng;
  if (draw.has_normals != 0u) {
    vec3 n = w * fetch_normal(i0) + u * fetch_normal(i1) + v * fetch_normal(i2);
    const float nl = length(n);
    if (nl > 1e-12 && !isinf(nl) && !isnan(nl)) {
      n /= nl;
      ns = dot(n, ng) < 0.0 ? -n : n;
    }
  }

  out_position_depth = vec4(p, dot(p - frame.eye.xyz, frame.forward.xyz));
  out_normal = vec4(ns, 0.0);
  out_ids = ivec2(draw.object, int(t - draw.first_triangle));
  out_barycentric = vec2(u, v);
}
