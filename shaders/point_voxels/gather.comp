#version 450
// Indirect light gathering (paper 002 section 3.3, eqs. 5-6) at the gathering resolution: each
// pixel takes the filtered lists (bitsets) of its four marching neighbours with linear weights w_l
// times joint bilateral w_G, normalised by their sum N_c (gather_taps); a voxel in several lists is
// gathered once with the sum of their weights, in increasing voxel order; voxels nearer than R are
// gathered VPL by VPL as discs, farther ones through their order-2 SH from their centroid
// (gather_voxel), diffuse and glossy (the Phong lobe, optionally weighted by eq. 7) apart. One
// invocation per gathering pixel that sees a surface (the host lists them; the background's keep
// their zeroed sums and cost no lane, where a SIMD device would run a subgroup's loops for its idle
// lanes too); under a driver's loop-iteration limit an invocation that runs out of budget saves its
// place and sums and the host dispatches again.
//
// The lanes of a subgroup walk one voxel sequence together: the union of their lists, in increasing
// voxel order, each lane adding only the voxels of its own list. Neighbouring pixels share most of
// their voxels, so the union is little longer than one list, and every voxel's data (its range, its
// centroid, its SH, its VPLs) is read at one address for all lanes instead of at as many addresses
// as lanes (a SIMD device fetches divergent addresses lane by lane). Each lane still sums its own
// voxels in the same order with the same operations: the results are those of one pixel alone.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_vote : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
// 0 where no gathering pixel of the frame is glossy (GLOSSY) or weighted by eq. 7 (EQ7): the host
// compiles that code out. A SIMD device runs both sides of a branch its lanes disagree on, and
// llvmpipe runs a branch's code even when no lane takes it, so the Phong lobe's pow (log2 and exp2
// series) and eq. 7's exp would cost every VPL of every diffuse frame.
layout(constant_id = 0) const uint GLOSSY = 1u;
layout(constant_id = 1) const uint EQ7 = 1u;
// What the loops read comes through texel buffers: a SIMD device fetches texels for all lanes at
// once, where it reads a storage buffer lane by lane. The proxies as RGBA32F texels, 4 per proxy
// (position, normal, ...); the marching pixels 3 per pixel (position and hit, normal and depth, ...).
layout(set = 0, binding = kPvGathBindProxies) uniform samplerBuffer discs;
layout(set = 0, binding = kPvGathBindRadiance) uniform samplerBuffer radiance;
layout(set = 0, binding = kPvGathBindStart) uniform usamplerBuffer cell_start;
layout(set = 0, binding = kPvGathBindSh) uniform samplerBuffer vsh;
layout(set = 0, binding = kPvGathBindMarch) uniform samplerBuffer pixels;
layout(set = 0, binding = kPvGathBindBits) uniform usamplerBuffer bits;
struct GatherPixel {
  vec4 pos_depth;
  vec4 normal_glossy;
  vec4 reflect_ns;
  vec4 extra;  // eq. 7 sigma (0: off), unused (0), (ns + 2) / (2 pi)
};
layout(std430, set = 0, binding = kPvGathBindReceivers) readonly buffer Receivers { GatherPixel recv[]; };
struct Gathered {
  vec4 irradiance;
  vec4 glossy;
  vec4 weighted;  // w: 1 when eq. 7 weighted a term
};
layout(std430, set = 0, binding = kPvGathBindOut) buffer Out { Gathered outv[]; };
struct GatherState {
  uvec4 s;
  vec4 esum;
};
layout(std430, set = 0, binding = kPvGathBindState) buffer State { GatherState state[]; };
layout(std430, set = 0, binding = kPvGathBindStatus) buffer Status { uint status[]; };
layout(std430, set = 0, binding = kPvGathBindSources) readonly buffer Sources { uint sources[]; };
layout(push_constant) uniform Push {
  uint first, end;
  int gw, mw, mh;
  uint words;
  float ratio;          // gathering scale / marching scale
  float sigma_depth, sigma_normal;
  float near2;          // R^2
  float reg;            // A / pi, the VPL disc's regulariser
  float eq7_norm;       // sigma sqrt(2 pi) / sigma: sqrt(2 pi)
  uint budget;
} pc;

Gathered acc;
GatherPixel rp;
float patch_area;  // the grid's g_cell_a.w, read once

// add_glossy: one light's glossy term E (ns + 2) / (2 pi) max(0, R . w)^ns, and eq. 7's.
void add_glossy(vec3 e, vec3 wn, float weight) {
  const float ca = dot(rp.reflect_ns.xyz, wn);
  if (ca <= 0.0) return;
  const float ns = rp.reflect_ns.w;
  const vec3 g = e * (rp.extra.z * pow(ca, ns));
  acc.glossy.xyz += weight * g;
  const float sigma = rp.extra.x;
  if (EQ7 != 0u && sigma > 0.0) {
    // eq7_weight times its peak's inverse sigma sqrt(2 pi): 1 at the reflection vector.
    const float x = abs(1.0 - pow(max(0.0, ca), ns)) / sigma;
    const float rel = exp(-0.5 * x * x) / (sigma * pc.eq7_norm) * (sigma * pc.eq7_norm);
    acc.weighted.xyz += weight * rel * g;
    acc.weighted.w = 1.0;
  }
}

// The voxel's light from its centroid through its SH (eq. 6, second case; eqs. 2-3).
void gather_far(uint k, float weight, vec3 to_c, float dc2) {
  const float dc = sqrt(dc2);
  const vec3 wn = to_c / dc;
  const float cos_r = dot(rp.normal_glossy.xyz, wn);
  if (cos_r <= 0.0) return;
  const vec4 y = pv_basis2(-wn);
  const int o = int(k * kPvVoxelFloats);
  const vec3 c0 = vec3(texelFetch(vsh, o).x, texelFetch(vsh, o + 1).x, texelFetch(vsh, o + 2).x);
  const vec3 c1 = vec3(texelFetch(vsh, o + 3).x, texelFetch(vsh, o + 4).x, texelFetch(vsh, o + 5).x);
  const vec3 c2 = vec3(texelFetch(vsh, o + 6).x, texelFetch(vsh, o + 7).x, texelFetch(vsh, o + 8).x);
  const vec3 c3 = vec3(texelFetch(vsh, o + 9).x, texelFetch(vsh, o + 10).x, texelFetch(vsh, o + 11).x);
  const vec3 intensity = max(vec3(0.0), c0 * y[0] + c1 * y[1] + c2 * y[2] + c3 * y[3]);
  const vec3 ei = intensity * (cos_r / dc2);
  acc.irradiance.xyz += weight * ei;
  if (GLOSSY != 0u && rp.normal_glossy.w > 0.0) add_glossy(ei, wn, weight);
}

// One VPL of a near voxel: a disc of area A (eq. 6, first case), at `pos` with normal `nrm` and
// radiance `rad`.
void gather_vpl(vec3 pos, vec3 nrm, vec3 rad, float weight, inout vec3 esum) {
  const vec3 w = pos - rp.pos_depth.xyz;
  const float d2 = dot(w, w);
  if (GLOSSY == 0u || !(rp.normal_glossy.w > 0.0)) {
    // A diffuse receiver as the CPU's near_diffuse (pv_core.cpp): cos_r cos_v = (n_r . w)(-n_i . w) / d^2,
    // without the square root and the direction's divisions that only the glossy lobe needs.
    const float dr = dot(rp.normal_glossy.xyz, w), dv = -dot(nrm, w);
    const bool ok = d2 > 0.0 && dr > 0.0 && dv > 0.0;
    const float f = patch_area * (dr * dv) / (d2 * (d2 + pc.reg));
    esum += rad * (ok ? f : 0.0);
    return;
  }
  if (!(d2 > 0.0)) return;
  const vec3 wn = w / sqrt(d2);
  const float cos_r = dot(rp.normal_glossy.xyz, wn), cos_v = -dot(nrm, wn);
  if (cos_r <= 0.0 || cos_v <= 0.0) return;
  const vec3 ei = rad * (patch_area * cos_v * cos_r / (d2 + pc.reg));
  esum += ei;
  add_glossy(ei, wn, weight);
}

void main() {
  const uint j = pc.first + gl_GlobalInvocationID.x;
  if (j >= pc.end) return;
  const uint i = sources[j];
  GatherState st = state[i];
  if (st.s.x == kPvPhaseDone) return;
  rp = recv[i];
  patch_area = g_cell_a.w;
  // gather_taps (point_voxels.cpp): eq. 5's weights over the four marching neighbours.
  const int x = int(i % uint(pc.gw)), y = int(i / uint(pc.gw));
  const float u = (float(x) + 0.5) * pc.ratio - 0.5, v = (float(y) + 0.5) * pc.ratio - 0.5;
  const int x0 = int(floor(u)), y0 = int(floor(v));
  const float fx = u - float(x0), fy = v - float(y0);
  uint tq[4];
  float wl[4], wg[4];
  int nt = 0;
  for (int j = 0; j < 2; ++j)
    for (int k = 0; k < 2; ++k) {
      const int qx = clamp(x0 + k, 0, pc.mw - 1), qy = clamp(y0 + j, 0, pc.mh - 1);
      const uint q = uint(qy) * uint(pc.mw) + uint(qx);
      if (texelFetch(pixels, int(3u * q)).w == 0.0) continue;
      wl[nt] = (k != 0 ? fx : 1.0 - fx) * (j != 0 ? fy : 1.0 - fy);
      const vec4 normal_depth = texelFetch(pixels, int(3u * q + 1u));
      const float dz = (normal_depth.w - rp.pos_depth.w) / (pc.sigma_depth * rp.pos_depth.w);
      const float dn = (1.0 - dot(normal_depth.xyz, rp.normal_glossy.xyz)) / pc.sigma_normal;
      wg[nt] = exp(-0.5 * (dz * dz + dn * dn));
      tq[nt++] = q;
    }
  float nc = 0.0, nl = 0.0;
  for (int k = 0; k < nt; ++k) {
    nc += wl[k] * wg[k];
    nl += wl[k];
  }
  const bool geometric = nc > 1e-4 * nl;
  const float norm = geometric ? nc : nl;
  if (st.s.x == kPvPhaseNew && !geometric) atomicAdd(status[kPvStatusUnmatched], 1u);
  if (!(norm > 0.0)) {
    state[i].s = uvec4(kPvPhaseDone, 0u, 0u, 0u);
    return;
  }
  uint used = 0u;
  float tw[4];
  uint tb[4];
  for (int k = 0; k < nt; ++k) {
    const float w = (geometric ? wl[k] * wg[k] : wl[k]) / norm;
    if (w > 0.0) {
      tw[used] = w;
      tb[used++] = tq[k] * pc.words;
    }
  }
  // A voxel's weights are summed in increasing order, as the CPU's sorted (voxel, weight) pairs.
  for (uint a = 1u; a < used; ++a)
    for (uint b = a; b > 0u && tw[b] < tw[b - 1u]; --b) {
      const float w = tw[b];
      tw[b] = tw[b - 1u];
      tw[b - 1u] = w;
      const uint t = tb[b];
      tb[b] = tb[b - 1u];
      tb[b - 1u] = t;
    }

  // The union of the neighbours' bitset words (this lane's list), and of the subgroup's lists.
  // After a resume every lane of the subgroup restarts at the same place: they all stopped there.
  uint tbits[4] = uint[4](0u, 0u, 0u, 0u);
  acc = outv[i];
  const uint resume_voxel = st.s.y;
  uint gathered = st.s.w, word = resume_voxel / 32u, mine = 0u, m = 0u;
  if (word < pc.words) {
    [[unroll]] for (uint t = 0u; t < 4u; ++t) tbits[t] = t < used ? texelFetch(bits, int(tb[t] + word)).x : 0u;
    mine = (tbits[0] | tbits[1] | tbits[2] | tbits[3]) & ~((1u << (resume_voxel % 32u)) - 1u);
  }
  m = subgroupOr(mine);
  // The outer loop's iterations are bitset words and voxels, the inner loop's a near voxel's VPLs;
  // the subgroup runs both together, so `spent` is the same in every lane and counts what the SIMD
  // batch runs (pv_march says why).
  uint vox = 0u, cell_b = 0u, vi = 0u, ve = 0u;
  float weight = 0.0;
  vec3 esum = vec3(0.0);
  bool near_voxel = false, near_mine = false;
  uint spent = 0u;
  for (;;) {
    if (++spent > pc.budget) {
      outv[i] = acc;
      // esum.w = 1: stopped inside the voxel's VPLs, its far lanes have gathered it already.
      if (near_voxel) state[i] = GatherState(uvec4(kPvPhaseResume, vox, vi - cell_b, gathered), vec4(esum, 1.0));
      else state[i] = GatherState(uvec4(kPvPhaseResume, m != 0u ? word * 32u + uint(findLSB(m)) : (word + 1u) * 32u, 0u, gathered), vec4(0.0));
      atomicAdd(status[kPvStatusUnfinished], 1u);
      return;
    }
    if (near_voxel) {
      // The voxel's VPLs in a loop of their own: a SIMD device runs every branch of the outer
      // loop's body for every iteration (masked), so each VPL would pay for the voxel's and the
      // word's code too. Its iterations count in `spent` like the outer loop's.
      while (vi < ve && spent < pc.budget) {
        ++spent;
        if (near_mine) {
          const int k = int(4u * vi);
          gather_vpl(texelFetch(discs, k).xyz, texelFetch(discs, k + 1).xyz, texelFetch(radiance, int(vi)).xyz, weight, esum);
        }
        ++vi;
      }
      if (vi < ve) {
        spent = pc.budget;  // out of budget: the next iteration saves the place
        continue;
      }
      if (near_mine) {
        acc.irradiance.xyz += weight * esum;
        ++gathered;
      }
      near_voxel = false;
      continue;
    }
    if (m != 0u) {
      const uint bit = uint(findLSB(m));
      m &= m - 1u;
      vox = word * 32u + bit;
      const bool listed = ((mine >> bit) & 1u) != 0u;
      // A voxel's weights are summed in increasing order (the taps are sorted by weight).
      weight = 0.0;
      [[unroll]] for (uint t = 0u; t < 4u; ++t)
        if (t < used && ((tbits[t] >> bit) & 1u) != 0u) weight += tw[t];
      cell_b = texelFetch(cell_start, int(vox)).x;
      ve = texelFetch(cell_start, int(vox + 1u)).x;
      if (cell_b == ve) {
        if (listed) ++gathered;
        continue;
      }
      const int co = int(vox * kPvVoxelFloats);
      const vec3 cen = vec3(texelFetch(vsh, co + 12).x, texelFetch(vsh, co + 13).x, texelFetch(vsh, co + 14).x);
      const vec3 to_c = cen - rp.pos_depth.xyz;
      const float dc2 = dot(to_c, to_c);
      near_mine = listed && dc2 < pc.near2;
      const bool inside = st.s.x == kPvPhaseResume && vox == resume_voxel && st.esum.w != 0.0;
      if (subgroupAny(near_mine)) {
        vi = cell_b + (inside ? st.s.z : 0u);
        esum = inside ? st.esum.xyz : vec3(0.0);
        near_voxel = true;
      }
      if (listed && !near_mine && !inside) {
        gather_far(vox, weight, to_c, dc2);
        ++gathered;
      }
      continue;
    }
    if (++word >= pc.words) break;
    [[unroll]] for (uint t = 0u; t < 4u; ++t) tbits[t] = t < used ? texelFetch(bits, int(tb[t] + word)).x : 0u;
    mine = tbits[0] | tbits[1] | tbits[2] | tbits[3];
    m = subgroupOr(mine);
  }
  outv[i] = acc;
  state[i].s = uvec4(kPvPhaseDone, 0u, 0u, gathered);
  atomicAdd(status[kPvStatusCount], gathered);
}
