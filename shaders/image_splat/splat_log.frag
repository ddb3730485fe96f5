#version 450
// image_splat's shadow splats, fragment stage (paper 000 section 4.1, Figure 3): the receiver at
// this pixel of the receiver buffer gets proxy `proxy`'s log occlusion vector (paper 004 eq. 38,
// with the replacement rules of section 6.2) through accum_log_pair, the step accumulate_log.comp
// takes per listed blocker; additive blending into RGBA32F attachments sums the proxies in draw
// order, which is proxy order, as the tile lists hold them. Each draw writes 4 OUTS coefficients from
// FIRST on (specialisation constants: the coefficients stay in registers).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#include "image_splat_splat_shared.h"
#define SHEXP_BASIS_BINDING kSplatBindBasis
#include "sh_basis.glsl"
#include "accum_math.glsl"

layout(constant_id = 0) const uint N = SH_PLAN_FIXED_ORDER;  // shadow order
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(constant_id = 3) const uint FIRST = 0;  // coefficient written to attachment 0's x
// Attachments: min(ceil(N^2 / 4), kSplatMaxAttachments), as image_splat_vulkan_splat.cpp draws them.
#if SH_PLAN_FIXED_ORDER <= 2
#define OUTS 1
#elif SH_PLAN_FIXED_ORDER == 3
#define OUTS 3
#elif SH_PLAN_FIXED_ORDER == 4
#define OUTS 4
#elif SH_PLAN_FIXED_ORDER == 5
#define OUTS 7
#else
#define OUTS 8
#endif
const uint W4 = (N + 3u) / 4u;

layout(set = 0, binding = kSplatBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kSplatBindPixelReceiver) uniform isamplerBuffer pixel_receiver;
layout(set = 0, binding = kSplatBindTest) uniform samplerBuffer test;
layout(set = 0, binding = kSplatBindSpheres) uniform samplerBuffer spheres;
layout(set = 0, binding = kSplatBindWeights) uniform samplerBuffer weights4;
layout(set = 0, binding = kSplatBindTable) uniform samplerBuffer table2;
#include "accum_log_pair.glsl"
layout(push_constant) uniform Push {
  mat4 clip_from_world;
  vec4 eye_pixel;
  vec4 forward;
  uvec4 sizes;  // buffer width, receivers, table rows
  vec4 table;   // table scale, per-pair cut factor (0: none)
} pc;
layout(location = 0) flat in uint proxy;
layout(location = 0) out vec4 o0;
#if OUTS > 1
layout(location = 1) out vec4 o1;
#endif
#if OUTS > 2
layout(location = 2) out vec4 o2;
#endif
#if OUTS > 3
layout(location = 3) out vec4 o3;
#endif
#if OUTS > 4
layout(location = 4) out vec4 o4;
#endif
#if OUTS > 5
layout(location = 5) out vec4 o5;
#endif
#if OUTS > 6
layout(location = 6) out vec4 o6;
#endif
#if OUTS > 7
layout(location = 7) out vec4 o7;
#endif

float coef(const float acc[kAccumMaxCoeffs], uint c) { return c < N * N ? acc[c] : 0.0; }
vec4 quad(const float acc[kAccumMaxCoeffs], uint a) {
  const uint c = FIRST + 4u * a;
  return vec4(coef(acc, c), coef(acc, c + 1u), coef(acc, c + 2u), coef(acc, c + 3u));
}

void main() {
  const ivec2 px = ivec2(gl_FragCoord.xy);
  const int i = texelFetch(pixel_receiver, px.y * int(pc.sizes.x) + px.x).x;
  if (i < 0) discard;  // background
  const int n = int(pc.sizes.y);
  const vec3 P = vec3(texelFetch(rec, i).x, texelFetch(rec, n + i).x, texelFetch(rec, 2 * n + i).x);
  const vec3 Nrm = vec3(texelFetch(rec, 3 * n + i).x, texelFetch(rec, 4 * n + i).x, texelFetch(rec, 5 * n + i).x);
  // Figure 3's depth test: "only pixels inside need be processed further". Without a per-pair cut,
  // a receiver outside the sphere of influence reads exactly 0 from the clamped table under every
  // replacement rule that has no cut (the rules only shrink the angle the proxy subtends), which is
  // why the binned lists may hold such pairs; here they cost neither the pair nor the blend.
  if (pc.table.y == 0.0) {
    const vec4 reach = texelFetch(test, int(proxy));
    if (!(distance(reach.xyz, P) < reach.w)) discard;
  }
  vec3 sh_dir;
  float fl[kAccumMaxOrder];
  if (!accum_log_pair(texelFetch(spheres, int(proxy)), proxy, P, Nrm, pc.table.y, pc.table.x, pc.sizes.z, sh_dir, fl)) discard;
  float acc[kAccumMaxCoeffs];
  [[unroll]] for (uint c = 0; c < N * N; ++c) acc[c] = 0.0;
  { SH_BASIS_UNROLLED(N) }
  o0 = quad(acc, 0u);
#if OUTS > 1
  o1 = quad(acc, 1u);
#endif
#if OUTS > 2
  o2 = quad(acc, 2u);
#endif
#if OUTS > 3
  o3 = quad(acc, 3u);
#endif
#if OUTS > 4
  o4 = quad(acc, 4u);
#endif
#if OUTS > 5
  o5 = quad(acc, 5u);
#endif
#if OUTS > 6
  o6 = quad(acc, 6u);
#endif
#if OUTS > 7
  o7 = quad(acc, 7u);
#endif
}
