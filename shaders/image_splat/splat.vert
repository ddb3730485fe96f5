#version 450
// image_splat's splats (paper 000 section 4.1, Figure 3), shadows (splat_log.frag) and indirect light
// (splat_indirect.frag): one instance per proxy draws a coarsely tessellated sphere bounding the
// proxy's sphere of influence into the receiver buffer, as the viewpoint sees it. The pipelines cull
// front faces, so that each pixel whose ray meets the hull gets exactly one fragment per proxy (its
// far side), also where the eye is inside the hull; the fragment tests the pixel's receiver against
// the sphere. A sphere of influence of infinite radius (no coverage oracle) is one triangle over the
// whole buffer.
#extension GL_GOOGLE_include_directive : require
#include "image_splat_splat_shared.h"

layout(set = 0, binding = kSplatBindTest) uniform samplerBuffer test;
layout(set = 0, binding = kSplatBindHull) uniform samplerBuffer hull;
layout(push_constant) uniform Push {
  mat4 clip_from_world;  // vulkan::clip_from_world of the receiver buffer
  vec4 eye_pixel;        // eye position; w: a buffer pixel's width at unit depth
  vec4 forward;          // image-plane normal E
  uvec4 sizes;           // buffer width, receivers, table rows
  vec4 table;            // table scale, per-pair cut factor (0: none; indirect light: eta)
} pc;
layout(location = 0) flat out uint proxy;

void main() {
  const uint b = uint(gl_InstanceIndex);
  proxy = b;
  const vec4 s = texelFetch(test, int(b));
  if (isinf(s.w)) {
    // (-1, -1), (3, -1), (-1, 3): clockwise on screen, so back-facing like the hull's far side.
    const int v = gl_VertexIndex;
    gl_Position = v == 0 ? vec4(-1.0, -1.0, 1.0, 1.0) : v == 1 ? vec4(3.0, -1.0, 1.0, 1.0) : v == 2 ? vec4(-1.0, 3.0, 1.0, 1.0) : vec4(0.0);
    return;
  }
  const float far_depth = max(dot(s.xyz - pc.eye_pixel.xyz, pc.forward.xyz), 0.0) + s.w;
  const float radius = s.w * (1.0 + kSplatHullMargin) + far_depth * pc.eye_pixel.w;
  gl_Position = pc.clip_from_world * vec4(s.xyz + radius * texelFetch(hull, gl_VertexIndex).xyz, 1.0);
}
