#version 450
// image_splat's indirect accumulation (paper 000 section 5): per receiver p, the sum over its tile's
// re-radiating proxies of albedo_i / pi (I_i . H(N_p)) (eq. 10's second term before the eq. 12
// normalisation) and of omega_i (eq. 2), for the point-sampled (eq. 13), averaged (eq. 15) and exact
// (eqs. 16-17) operators. One invocation per receiver, summing its tile's list in order; the
// per-proxy step (indirect_pair.glsl) follows IndirectEvaluator::accumulate and Impl::pair
// (techniques/image_splat/indirect_evaluator.cpp) step by step.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#include "texels.glsl"
#include "image_splat_indirect_shared.h"

layout(constant_id = 0) const uint N = 3;  // indirect order
#define SHEXP_BASIS_BINDING kIndBindBasis
#define SHEXP_BASIS_ORDER N
#include "sh_basis.glsl"
#include "accum_math.glsl"
#include "replacement_rule.glsl"
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(constant_id = 2) const uint OP = kIndOpAveraged;
layout(local_size_x = kIndGroup) in;

layout(set = 0, binding = kIndBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kIndBindReceiverList) uniform usamplerBuffer rlist;
layout(set = 0, binding = kIndBindListRange) uniform usamplerBuffer ranges;
layout(set = 0, binding = kIndBindProxies) uniform samplerBuffer proxies;
layout(set = 0, binding = kIndBindAlbedo) uniform samplerBuffer albedo;
layout(set = 0, binding = kIndBindVis) uniform samplerBuffer vis;
layout(set = 0, binding = kIndBindDfac) uniform samplerBuffer dfac;
layout(std140, set = 0, binding = kIndBindConsts) uniform IndConsts { vec4 consts_v[kIndConstFloats / 4u]; };
layout(std430, set = 0, binding = kIndBindOut) buffer Out { vec4 outv[]; };
layout(std430, set = 0, binding = kIndBindPairs) buffer Pairs { uint pairs_inside; };
layout(set = 0, binding = kIndBindMtab) uniform samplerBuffer mtab;
layout(set = 0, binding = kIndBindQrot) uniform samplerBuffer qrot;
#include "indirect_pair.glsl"
layout(push_constant) uniform Push {
  uint count;   // receivers in all (the planes of rec are this long)
  uint first;   // first receiver of this dispatch
  uint end;     // one past the last receiver of this dispatch
  uint rows;    // table rows
  float scale;  // theta -> row coordinate
  float eta;    // sphere of influence: pairs with |c - p| >= eta r are cut (<= 0: none)
  uint chunk_first;  // this dispatch sums proxies [chunk_first, chunk_first + chunk_count) of each list
  uint chunk_count;  // (a driver's loop-iteration limit caps what one invocation may loop over)
  uint chunk_add;    // 1: add to the sums of the chunks before (read back from outv); 0: the first chunk
  float reach;       // IndirectSetup::reach (0: none)
} pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const vec3 P = vec3(texel1(rec, i), texel1(rec, pc.count + i), texel1(rec, 2 * pc.count + i));
  const vec3 Nrm = vec3(texel1(rec, 3 * pc.count + i), texel1(rec, 4 * pc.count + i), texel1(rec, 5 * pc.count + i));
  const uvec2 range = texelFetch(ranges, int(texelFetch(rlist, int(i)).x)).xy;
  if (pc.chunk_add != 0u && pc.chunk_first >= range.y) return;  // this list ended in an earlier chunk
  const vec4 before = pc.chunk_add != 0u ? outv[i] : vec4(0.0);
  vec3 acc = before.xyz;
  float om = before.w;
  uint inside = 0;
  const uint j_end = range.x + min(range.y, pc.chunk_first + pc.chunk_count);
  for (uint j = range.x + pc.chunk_first; j < j_end; ++j) {
    vec3 light;
    float omega;
    if (!indirect_pair(texelFetch(proxies, int(j)), texelFetch(albedo, int(j)).xyz, P, Nrm, pc.eta, pc.reach, pc.scale, pc.rows, light, omega)) continue;
    ++inside;
    om += omega;
    acc += light;
  }
  outv[i] = vec4(acc, om);
  if (inside > 0u) atomicAdd(pairs_inside, inside);
}
