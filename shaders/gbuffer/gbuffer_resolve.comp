#version 450
#extension GL_GOOGLE_include_directive : require
// G-buffer resolve: position, depth and normal of every pixel from the visibility buffer (object,
// primitive, b1, b2) that gbuffer_raster rasterised. The CPU G-buffer's per-hit rules
// (backends/cpu/gbuffer_cpu.cpp, shade_hit) applied to the rasterised barycentrics, with the
// triangle's corners fetched from the same posed vertex arrays, so that both backends compute
// position, normal and depth with the same arithmetic from (object, primitive, b1, b2).
#include "gbuffer_common.glsl"

layout(local_size_x = kGbResolveGroup) in;

layout(set = 0, binding = kGbBindObjects, std430) readonly buffer GbObjects { uvec2 objects[]; };
layout(set = 0, binding = kGbBindIds, std430) readonly buffer GbIds { ivec2 ids[]; };
layout(set = 0, binding = kGbBindBarycentric, std430) readonly buffer GbBary { vec2 bary[]; };
layout(set = 0, binding = kGbBindPositionDepth, std430) writeonly buffer GbPosDepth { vec4 position_depth[]; };
layout(set = 0, binding = kGbBindNormal, std430) writeonly buffer GbNormal { vec4 normal_out[]; };

layout(push_constant, std430) uniform GbResolve {
  uint width, height;  // of this buffer
} pc;

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.width * pc.height) return;
  const ivec2 id = ids[i];
  if (id.x < 0) {  // background: depth +inf, as the host G-buffer holds it
    position_depth[i] = vec4(0.0);
    normal_out[i] = vec4(0.0, 0.0, 0.0, uintBitsToFloat(0x7f800000u));
    return;
  }
  const uvec2 obj = objects[id.x];
  const float u = bary[i].x, v = bary[i].y, w = 1.0 - u - v;
  const uint t = obj.x + uint(id.y);
  const uint i0 = fetch_index(3u * t), i1 = fetch_index(3u * t + 1u), i2 = fetch_index(3u * t + 2u);
  const vec3 p0 = fetch_position(i0), p1 = fetch_position(i1), p2 = fetch_position(i2);
  const vec3 p = w * p0 + u * p1 + v * p2;

  // The camera ray of this pixel: render::PinholeCamera::direction at display point
  // ((x + 0.5) s, (y + 0.5) s), the rasteriser's pixel centre.
  const float W = frame.image.x, H = frame.image.y, s = frame.image.z, tan_half = frame.image.w;
  const float px = (float(i % pc.width) + 0.5) * s, py = (float(i / pc.width) + 0.5) * s;
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
  if (obj.y != 0u) {
    vec3 n = w * fetch_normal(i0) + u * fetch_normal(i1) + v * fetch_normal(i2);
    const float nl = length(n);
    if (nl > 1e-12 && !isinf(nl) && !isnan(nl)) {
      n /= nl;
      ns = dot(n, ng) < 0.0 ? -n : n;
    }
  }

  // The depth twice: beside the position (the host's depth plane) and beside the normal, so that
  // a later pass reads a pixel's normal and depth with one fetch (upsample_weights.comp's layout).
  const float depth = dot(p - frame.eye.xyz, frame.forward.xyz);
  position_depth[i] = vec4(p, depth);
  normal_out[i] = vec4(ns, depth);
}
