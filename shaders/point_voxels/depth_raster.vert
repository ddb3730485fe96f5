#version 450
// The lights' depth maps (paper 002 Figure 2a) rasterised: every posed triangle into one face of a
// local light's cube map or into the sun's directional map, depth only. The projections are those of
// rasterize_cube_depth and rasterize_ortho_depth (pv_core.cpp), so that the rasteriser samples the
// same texel centres:
//  - cube face (axis a, sign s): x_c = d[(a + 1) % 3], y_c = d[(a + 2) % 3], w_c = z = s d[a] with
//    d = p - centre; z_c = near: reverse Z, depth near / z (compare greater, cleared to 0), so that
//    the stored depth is near times the perspective-correct 1/z the CPU interpolates, and triangles
//    nearer than `near` are clipped as the CPU clips them;
//  - directional map: x, y from (p . u - lo) / extent, depth (z_hi + p . dir) / (z_hi - z_lo), so
//    that the same compare (greater, cleared to 0) keeps the nearest.
// depth_resolve.comp turns the depths into the CPU maps' distances.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"

layout(std430, set = 0, binding = kPvRasterBindCorners) readonly buffer Corners { vec4 corner[]; };
layout(push_constant) uniform Push {
  vec4 center_near;  // cube: centre, near
  ivec4 mode_axes;   // mode, a, (a + 1) % 3, (a + 2) % 3
  vec4 params;       // cube: sign; ortho: z_hi, -1 / (z_hi - z_lo)
  vec4 u_lo;         // ortho: u, lo.x
  vec4 v_lo;         // ortho: v, lo.y
  vec4 dir;          // ortho: towards the light
  vec4 extent;       // ortho: extent.x, extent.y
} pc;

void main() {
  const vec3 p = corner[gl_VertexIndex].xyz;
  if (pc.mode_axes.x == int(kPvRasterCube)) {
    const vec3 d = p - pc.center_near.xyz;
    gl_Position = vec4(d[pc.mode_axes.z], d[pc.mode_axes.w], pc.center_near.w, pc.params.x * d[pc.mode_axes.y]);
  } else {
    const float x = (dot(p, pc.u_lo.xyz) - pc.u_lo.w) / pc.extent.x * 2.0 - 1.0;
    const float y = (dot(p, pc.v_lo.xyz) - pc.v_lo.w) / pc.extent.y * 2.0 - 1.0;
    gl_Position = vec4(x, y, (-dot(p, pc.dir.xyz) - pc.params.x) * pc.params.y, 1.0);
  }
}
