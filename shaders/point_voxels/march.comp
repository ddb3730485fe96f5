#version 450
// Sparse ray marching (paper 002 section 3.1): one invocation per (source, ray). The source is a
// marching pixel (its shadow rays, Figure 2c-d) or a proxy (its environment rays, the extension that
// lights VPLs by the sky); the ray is the k-th of the source's cosine-distributed set, and the first
// voxel whose discs it hits ends it (march_ray). Escaped rays carry the sky's radiance. Under a
// driver's loop-iteration limit an invocation that runs out of budget saves where it stopped and the
// host dispatches again (pv_march).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_vote : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(constant_id = 0) const uint SOURCE = kPvSourcePixels;
layout(local_size_x = kPvGroup) in;

layout(std430, set = 0, binding = kPvMarchBindProxies) readonly buffer Proxies { Proxy prox[]; };
layout(set = 0, binding = kPvMarchBindStart) uniform usamplerBuffer cell_start;
layout(set = 0, binding = kPvMarchBindDiscs) uniform samplerBuffer discs;
layout(std430, set = 0, binding = kPvMarchBindPixels) readonly buffer Pixels { MarchPixel pixels[]; };
layout(std430, set = 0, binding = kPvMarchBindSky) readonly buffer Sky { vec4 sky_sh[]; };
layout(std430, set = 0, binding = kPvMarchBindItems) buffer Items { MarchItem items[]; };
layout(std430, set = 0, binding = kPvMarchBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  uint first_source;  // the items of this batch are (first_source + s, k) for s < sources
  uint sources;
  uint rays;          // per source
  uint sky;           // 1: escaped rays carry the sky's radiance
  uint budget;        // loop iterations per invocation and dispatch
  uint first, end;    // items of this dispatch (batch-relative)
} pc;

#define PV_SKY
#include "pv_march.glsl"

void main() {
  const uint item = pc.first + gl_GlobalInvocationID.x;
  if (item >= pc.end) return;
  uvec4 st = items[item].state;
  if (st.x == kPvPhaseDone) return;
  const uint src = pc.first_source + item / pc.rays, k = item % pc.rays;
  vec3 p, n;
  uint seed;
  if (SOURCE == kPvSourcePixels) {
    const MarchPixel px = pixels[src];
    if (px.pos_hit.w == 0.0) {
      items[item].state = uvec4(kPvPhaseDone, 0u, 0u, uint(-1));
      items[item].radiance = vec4(0.0);
      return;
    }
    p = px.pos_hit.xyz;
    n = px.normal_depth.xyz;
    seed = px.seed.x;
  } else {
    p = prox[src].position.xyz;
    n = prox[src].normal.xyz;
    seed = prox[src].meta.x;
  }
  const float r = g_lo_r.w;
  const vec3 o = p + n * (0.25 * r);
  const vec2 u = pv_ray_sample(k, pc.rays, seed);
  const vec3 d = pv_cosine_direction(n, u.x, u.y);
  uint steps = st.x == kPvPhaseResume ? st.y : 0u, disc = st.x == kPvPhaseResume ? st.z : 0u;
  const int hit = pv_march(o, d, 0.5 * r, 1e30, steps, disc, pc.budget);
  if (hit == -2) {
    items[item].state = uvec4(kPvPhaseResume, steps, disc, 0u);
    atomicAdd(status[kPvStatusUnfinished], 1u);
    return;
  }
  items[item].state = uvec4(kPvPhaseDone, 0u, 0u, uint(hit));
  items[item].radiance = vec4(hit < 0 && pc.sky != 0u ? pv_sky_radiance(d) : vec3(0.0), 0.0);
}
