#version 450
// Sparse ray marching (paper 002 section 3.1): one invocation per (source, ray). The source is a
// marching pixel (its shadow rays, Figure 2c-d) or a proxy (its environment rays, the extension that
// lights VPLs by the sky); the ray is the k-th of the source's cosine-distributed set, and the first
// voxel whose discs it hits ends it (march_ray). Escaped rays carry the sky's radiance. The
// invocation marches its own ray (LANES = 0, pv_march), or the subgroup marches its lanes' rays one
// after another, each ray's discs spread over the lanes (LANES = 1, pv_march_lanes). Under a
// driver's loop-iteration limit a ray that runs out of budget saves where it stopped and the host
// dispatches again.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(constant_id = 0) const uint SOURCE = kPvSourcePixels;
// 1: a ray's discs tested across the subgroup's lanes, the subgroup's rays one at a time
// (pv_march_lanes); 0: one ray per invocation (pv_march).
layout(constant_id = 1) const uint LANES = 1u;
layout(local_size_x = kPvGroup) in;

layout(std430, set = 0, binding = kPvMarchBindProxies) readonly buffer Proxies { Proxy prox[]; };
layout(set = 0, binding = kPvMarchBindStart) uniform usamplerBuffer cell_start;
layout(set = 0, binding = kPvMarchBindDiscs) uniform samplerBuffer discs;
layout(std430, set = 0, binding = kPvMarchBindPixels) readonly buffer Pixels { MarchPixel pixels[]; };
layout(std430, set = 0, binding = kPvMarchBindSky) readonly buffer Sky { vec4 sky_sh[]; };
layout(std430, set = 0, binding = kPvMarchBindItems) buffer Items { MarchItem items[]; };
layout(std430, set = 0, binding = kPvMarchBindStatus) buffer Status { uint status[]; };
// SOURCE == kPvSourcePixels: the marching pixels that see a surface, so that no invocation (nor, on
// a SIMD device that runs a subgroup's loops for its idle lanes too, any lane) is spent on the
// background's.
layout(std430, set = 0, binding = kPvMarchBindSources) readonly buffer Sources { uint sources[]; };
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

// The lanes variant's rays, lane `slot` of subgroup s at s gl_SubgroupSize + slot: the subgroup
// takes its rays one after another from here. The host runs this variant only where subgroups tile
// the workgroup (their size divides kPvGroup).
shared vec4 s_origin[kPvGroup];  // w: 1 when the ray is to be marched
shared vec4 s_dir[kPvGroup];
shared uvec2 s_place[kPvGroup];  // DDA steps before the current cell, next disc of it

void main() {
  const uint item = pc.first + gl_GlobalInvocationID.x;
  // With LANES every invocation stays to the end: the subgroup tests each ray's discs in all lanes.
  const uvec4 st = item < pc.end ? items[item].state : uvec4(kPvPhaseDone, 0u, 0u, 0u);
  bool live = st.x != kPvPhaseDone;
  vec3 o = vec3(0.0), d = vec3(0.0, 0.0, 1.0);
  if (live) {
    const uint src = pc.first_source + item / pc.rays, k = item % pc.rays;
    vec3 p, n;
    uint seed;
    if (SOURCE == kPvSourcePixels) {
      const MarchPixel px = pixels[sources[src]];
      p = px.pos_hit.xyz;
      n = px.normal_depth.xyz;
      seed = px.seed.x;
    } else {
      p = prox[src].position.xyz;
      n = prox[src].normal.xyz;
      seed = prox[src].meta.x;
    }
    o = p + n * (0.25 * g_lo_r.w);
    const vec2 u = pv_ray_sample(k, pc.rays, seed);
    d = pv_cosine_direction(n, u.x, u.y);
  }
  uint steps = st.x == kPvPhaseResume ? st.y : 0u, disc = st.x == kPvPhaseResume ? st.z : 0u;
  const float t_min = 0.5 * g_lo_r.w, t_max = 1e30;
  int hit = -2;
  if (LANES == 0u) {
    if (!live) return;
    hit = pv_march(o, d, t_min, t_max, steps, disc, pc.budget);
  } else {
    const uint base = gl_SubgroupID * gl_SubgroupSize, slot = base + gl_SubgroupInvocationID;
    s_origin[slot] = vec4(o, live ? 1.0 : 0.0);
    s_dir[slot] = vec4(d, 0.0);
    s_place[slot] = uvec2(steps, disc);
    subgroupMemoryBarrierShared();
    subgroupBarrier();
    // The rays one after another; one that runs out of budget leaves itself and the rest to the
    // next dispatch (hit stays -2 for those, with their places as they were).
    uint spent = 0u;
    for (uint j = 0u; j < gl_SubgroupSize; ++j) {
      if (++spent > pc.budget) break;
      const vec4 oj = s_origin[base + j];
      if (oj.w == 0.0) continue;
      uvec2 place = s_place[base + j];
      const int h = pv_march_lanes(oj.xyz, s_dir[base + j].xyz, t_min, t_max, place.x, place.y, pc.budget, spent);
      if (j == gl_SubgroupInvocationID) {
        hit = h;
        steps = place.x;
        disc = place.y;
      }
      if (h == -2) break;
    }
    if (!live) return;
  }
  if (hit == -2) {
    items[item].state = uvec4(kPvPhaseResume, steps, disc, 0u);
    atomicAdd(status[kPvStatusUnfinished], 1u);
    return;
  }
  items[item].state = uvec4(kPvPhaseDone, 0u, 0u, uint(hit));
  items[item].radiance = vec4(hit < 0 && pc.sky != 0u ? pv_sky_radiance(d) : vec3(0.0), 0.0);
}
