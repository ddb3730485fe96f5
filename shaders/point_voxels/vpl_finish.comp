#version 450
// Eqs. 2-3 per voxel (paper 002 section 3.3, Figure 2b): each VPL's radiant intensity L A max(0, n . w)
// projected to l <= 1 and summed over its cell, and the cell's position, the centroid of its VPLs.
// One invocation per cell sums the cell's VPLs in sorted order (sampling order within the cell,
// voxel_sort), term for term as accumulate_voxel_sh (pv_core.cpp), so that the sums are the same
// from run to run. Under a driver's loop limit the host runs the cells' VPLs in runs of at most
// pc.len, each dispatch going on from the sums the one before it stored; the run that reaches the
// cell's end divides the centroid.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvFinBindStart) readonly buffer Start { uint cell_start[]; };
layout(std430, set = 0, binding = kPvFinBindSh) buffer Sh { float vsh[]; };
layout(std430, set = 0, binding = kPvFinBindProxies) readonly buffer Proxies { Proxy prox[]; };
layout(std430, set = 0, binding = kPvFinBindRadiance) readonly buffer Radiance { vec4 radiance[]; };
layout(push_constant) uniform Push {
  uint first, end;  // cells of this dispatch
  uint from, len;   // the run of each cell's VPLs: [start + from, start + from + len)
} pc;

void main() {
  const uint k = pc.first + gl_GlobalInvocationID.x;
  if (k >= pc.end) return;
  const uint b = cell_start[k], e = cell_start[k + 1u];
  if (b + pc.from >= e) return;  // an empty cell keeps the zeros the host filled in
  const uint o = k * kPvVoxelFloats;
  vec3 s0 = vec3(0.0), s1 = vec3(0.0), s2 = vec3(0.0), s3 = vec3(0.0), c = vec3(0.0);
  if (pc.from > 0u) {
    s0 = vec3(vsh[o], vsh[o + 1u], vsh[o + 2u]);
    s1 = vec3(vsh[o + 3u], vsh[o + 4u], vsh[o + 5u]);
    s2 = vec3(vsh[o + 6u], vsh[o + 7u], vsh[o + 8u]);
    s3 = vec3(vsh[o + 9u], vsh[o + 10u], vsh[o + 11u]);
    c = vec3(vsh[o + 12u], vsh[o + 13u], vsh[o + 14u]);
  }
  // The ZH of max(0, cos) turned to the normal, times sqrt(4 pi / (2l + 1)): pi, 2 pi / 3.
  const float k0 = kPvPi, k1 = 2.0 * kPvPi / 3.0;
  // Without a limit pc.len is ~0u: the run's end is taken without forming b + from + len.
  const uint left = e - (b + pc.from);
  const uint run_end = left > pc.len ? b + pc.from + pc.len : e;
  for (uint i = b + pc.from; i < run_end; ++i) {
    c += prox[i].position.xyz;
    const vec4 y = pv_basis2(prox[i].normal.xyz);
    const vec3 la = radiance[i].xyz * g_cell_a.w;
    s0 += la * (k0 * y[0]);
    s1 += la * (k1 * y[1]);
    s2 += la * (k1 * y[2]);
    s3 += la * (k1 * y[3]);
  }
  if (run_end == e && e > b) c /= float(e - b);
  const vec3 sums[5] = vec3[5](s0, s1, s2, s3, c);
  for (uint m = 0u; m < 5u; ++m)
    for (uint ch = 0u; ch < 3u; ++ch) vsh[o + 3u * m + ch] = sums[m][ch];
  vsh[o + 15u] = 0.0;
}
