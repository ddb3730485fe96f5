#version 450
// image_splat's indirect splats, fragment stage (paper 000 sections 4.1 and 5, Figure 3): the
// receiver at this pixel of the receiver buffer gets proxy `proxy`'s albedo / pi (I . H(N_p)) and
// omega through indirect_pair, the step accumulate_indirect.comp takes per listed proxy; additive
// blending into one RGBA32F attachment (rgb, omega) sums the proxies in draw order, which is proxy
// order, as the tile lists hold them.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#include "texels.glsl"
#include "image_splat_indirect_shared.h"
#include "image_splat_splat_shared.h"

layout(constant_id = 0) const uint N = 3;  // indirect order
#define SHEXP_BASIS_BINDING kSplatBindBasis
#define SHEXP_BASIS_ORDER N
#include "sh_basis.glsl"
#include "accum_math.glsl"
#include "replacement_rule.glsl"
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(constant_id = 2) const uint OP = kIndOpAveraged;

layout(set = 0, binding = kSplatBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kSplatBindPixelReceiver) uniform isamplerBuffer pixel_receiver;
layout(set = 0, binding = kSplatIndBindProxies) uniform samplerBuffer proxies;
layout(set = 0, binding = kSplatIndBindAlbedo) uniform samplerBuffer albedo;
layout(set = 0, binding = kSplatIndBindVis) uniform samplerBuffer vis;
layout(set = 0, binding = kSplatIndBindDfac) uniform samplerBuffer dfac;
layout(std140, set = 0, binding = kSplatIndBindConsts) uniform IndConsts { vec4 consts_v[kIndConstFloats / 4u]; };
layout(set = 0, binding = kSplatIndBindMtab) uniform samplerBuffer mtab;
layout(set = 0, binding = kSplatIndBindQrot) uniform samplerBuffer qrot;
layout(std430, set = 0, binding = kSplatIndBindPairs) buffer Pairs { uint pairs_inside; };
#include "indirect_pair.glsl"
layout(push_constant) uniform Push {
  mat4 clip_from_world;
  vec4 eye_pixel;
  vec4 forward;
  uvec4 sizes;  // buffer width, receivers, table rows
  vec4 table;   // table scale, eta (<= 0: no cut), reach (0: none)
} pc;
layout(location = 0) flat in uint proxy;
layout(location = 0) out vec4 sums;

void main() {
  const ivec2 px = ivec2(gl_FragCoord.xy);
  const int i = texelFetch(pixel_receiver, px.y * int(pc.sizes.x) + px.x).x;
  if (i < 0) discard;  // background
  const int n = int(pc.sizes.y);
  const vec3 P = vec3(texelFetch(rec, i).x, texelFetch(rec, n + i).x, texelFetch(rec, 2 * n + i).x);
  const vec3 Nrm = vec3(texelFetch(rec, 3 * n + i).x, texelFetch(rec, 4 * n + i).x, texelFetch(rec, 5 * n + i).x);
  vec3 light;
  float omega;
  if (!indirect_pair(texelFetch(proxies, int(proxy)), texelFetch(albedo, int(proxy)).xyz, P, Nrm, pc.table.y, pc.table.z, pc.table.x, pc.sizes.z, light,
                     omega))
    discard;
  atomicAdd(pairs_inside, 1u);
  sums = vec4(light, omega);
}
