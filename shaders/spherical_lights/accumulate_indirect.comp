#version 450
// Spherical lights' receiver accumulation (paper 001 section 6), one invocation per receiver p with
// normal N: L^I_p / rho = sum_i Lbar_i Vbar_i (eqs. 13-15). Per SL: the replacement rules of paper
// 004 section 6.2 (shaders/include/replacement_rule.glsl), its log vector G_i (eq. 34: the cap log
// ZH table and the SHEXP basis recurrence, as accumulate_log.comp), its average radiance Lbar_i =
// w_theta . L^c (eqs. 16-18: the w_theta table, turned to the direction of p in the SL's rest
// frame). The active SLs are taken in blocking order (section 7.2: per sphere by distance; per
// object by object-centre distance, object, distance), S_i is the sum of the G of the SLs before S_i
// less those of its own object that intersect it (eq. 21), and Vbar_i = H(N) . (exp(S_i) -
// exp(S_i + G_i)) clamped at 0 (eqs. 23-24), the exponentials by the CPU's method (HYB or OL,
// shaders/include/sh_exp.glsl). The arithmetic follows receiver_terms in techniques/spherical_lights/
// sl_indirect.cpp step by step; the tables are the CPU's own floats, uploaded. The logs G are
// recomputed where needed rather than stored: only the SLs' order keys are held per invocation
// (kSlMaxLights each).
//
// Resumable passes: Mesa's llvmpipe (lavapipe) ends every loop of an invocation once all its loops
// together have iterated 65535 times (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS, one counter per SIMD
// batch), which silently truncates the squarings of a receiver with many SLs. So an invocation
// counts its loop iterations (as the batch does: the subgroup's largest trip count of each loop)
// and, before an SL would take it past pc.budget, saves its state (the prefix sum of G, the sum so
// far, the last SL summed) and stops; the host dispatches again until no receiver is unfinished.
// The next SL is found by a scan for the smallest (key, index) after the last one, so a pass needs
// no sorted order from the previous one. On other drivers the budget is unlimited: one pass.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "softgi_shared.h"
#include "texels.glsl"
#include "sl_shared.h"

layout(constant_id = 0) const uint N = SH_PLAN_FIXED_ORDER;  // SH order
#define SHEXP_BASIS_BINDING kSlIndBindBasis
#define SHEXP_BASIS_ORDER N
#include "sh_basis.glsl"
#include "accum_math.glsl"
#include "replacement_rule.glsl"
#define SH_EXP_N N
#define SH_EXP_BIND_OL kSlIndBindOl
#include "sh_exp.glsl"
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(constant_id = 2) const uint METHOD = kExpHyb;
layout(constant_id = 3) const uint BLOCKING = kSlPerSphere;
layout(local_size_x = kSlIndirectGroup) in;

layout(set = 0, binding = kSlIndBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kSlIndBindSpheres) uniform samplerBuffer spheres;
layout(set = 0, binding = kSlIndBindRotation) uniform samplerBuffer rotation;
layout(set = 0, binding = kSlIndBindObject) uniform usamplerBuffer object;
layout(set = 0, binding = kSlIndBindObjCentre) uniform samplerBuffer object_centre;
layout(set = 0, binding = kSlIndBindInterBegin) uniform usamplerBuffer inter_begin;
layout(set = 0, binding = kSlIndBindInterList) uniform usamplerBuffer inter_list;
layout(set = 0, binding = kSlIndBindIntensity) uniform samplerBuffer lc;
layout(set = 0, binding = kSlIndBindLogTable) uniform samplerBuffer log_table;
layout(set = 0, binding = kSlIndBindWeight) uniform samplerBuffer weight;
layout(set = 0, binding = kSlIndBindConsts) uniform samplerBuffer consts;
layout(std430, set = 0, binding = kSlIndBindOut) writeonly buffer Out { vec4 outv[]; };
layout(std430, set = 0, binding = kSlIndBindStatus) buffer Status { uint status[]; };
layout(set = 0, binding = kSlIndBindEntrySl) uniform usamplerBuffer entry_sl;
layout(set = 0, binding = kSlIndBindRatio) uniform samplerBuffer ratio;
layout(set = 0, binding = kSlIndBindRList) uniform usamplerBuffer rlist;
layout(set = 0, binding = kSlIndBindLists) uniform usamplerBuffer lists;
layout(std430, set = 0, binding = kSlIndBindState) buffer State { float state[]; };
layout(push_constant) uniform Push {
  uint count;         // receivers in all (the planes of rec are this long)
  uint first;         // first receiver of this dispatch
  uint end;           // one past the last
  uint lights;        // list entries in all
  uint log_rows;      // rows of the log table
  uint weight_rows;   // rows of the w_theta table
  uint ol_count;      // knots of the OL table
  float log_scale;    // log table: (rows - 1) / (pi/2)
  float weight_scale; // w_theta table: (rows - 1) / (pi/2)
  uint budget;        // loop iterations one invocation may run in this pass (0xffffffff: no limit)
  uint resume;        // 0: the first pass; 1: continue from the state
} pc;

float hcoef(uint l) { return texel1(consts, l); }
float zh_rot(uint l) { return texel1(consts, N + l); }

// The SL's sphere after the replacement rules at (P, Nrm); radius 0 where the rules eliminate it or
// p is not outside it.
vec4 sl_adjusted(uint k, vec3 P, vec3 Nrm) {
  const vec4 sph = texelFetch(spheres, int(k));
  vec4 adj = apply_replacement_rule(RULE, P, Nrm, sph.xyz, sph.w);
  const float dist = length(adj.xyz - P);
  if (!(adj.w > 0.0) || !(dist > adj.w)) adj.w = 0.0;
  return adj;
}

// Eq. 34 for a sphere at P (common::sphere_zh_vector): G = F(theta) y(s).
void sl_log_vector(vec4 adj, vec3 P, out float G[kAccumMaxCoeffs]) {
  const vec3 d = adj.xyz - P;
  const float dist = length(d);
  const float theta = accum_asin01(min(1.0, adj.w / dist));
  float u = theta * pc.log_scale;
  if (!(u > 0.0)) u = 0.0;
  const int kr = min(int(min(u, float(pc.log_rows - 1))), int(pc.log_rows) - 2);
  const float fr = u - float(kr);
  const uint row = uint(kr) * 2u * N;
  float Y[kAccumMaxCoeffs], F[kAccumMaxOrder];
  sh_basis_eval(d / dist, Y);
  [[unroll]] for (uint l = 0; l < N; ++l) F[l] = texel1(log_table, row + 2 * l) + fr * texel1(log_table, row + 2 * l + 1);
  [[unroll]] for (uint q = 0; q < N * N; ++q) G[q] = F[kShBand[q]] * Y[q];
}

// Eqs. 16-18: the SL's average radiance towards P (WeightTable::lookup, the rotated ZH dot product).
vec3 sl_average_radiance(uint k, vec3 P) {
  const vec4 sph = texelFetch(spheres, int(k));
  const vec3 d = P - sph.xyz;
  const float D = length(d);
  const float r = sph.w;
  const float theta = D > r ? accum_asin01(min(1.0, r / D)) : kAccumHalfPi;
  const vec3 u = D > 0.0 ? d / D : vec3(0.0);
  // transpose(R) u: into the SL's rest frame.
  const int rk = int(3 * k);
  const vec3 dl = D > 0.0 ? vec3(dot(texelFetch(rotation, rk).xyz, u), dot(texelFetch(rotation, rk + 1).xyz, u),
                                 dot(texelFetch(rotation, rk + 2).xyz, u))
                          : vec3(0.0, 0.0, 1.0);
  const float th = theta > 0.0 ? theta : 0.0;
  const float x = min(th, kAccumHalfPi) * pc.weight_scale;
  const int kw = min(int(x), int(pc.weight_rows) - 2);
  const float f = min(1.0, x - float(kw));
  float Y[kAccumMaxCoeffs];
  sh_basis_eval(dl, Y);
  const uint n2 = N * N, base = texel1(entry_sl, k) * 3 * n2;
  float wl[kAccumMaxOrder];
  [[unroll]] for (uint l = 0; l < N; ++l) {
    const float a = texel1(weight, uint(kw) * N + l), b = texel1(weight, uint(kw + 1) * N + l);
    wl[l] = (a + f * (b - a)) * zh_rot(l);
  }
  vec3 acc = vec3(0.0);
  [[unroll]] for (uint q = 0; q < n2; ++q)
    acc += (wl[kShBand[q]] * Y[q]) * vec3(texel1(lc, base + q), texel1(lc, base + n2 + q), texel1(lc, base + 2 * n2 + q));
  // Eq. 26: a parent of the hierarchy scaled by its reflection ratio.
  return acc * texelFetch(ratio, int(k)).xyz;
}

float key_[kSlMaxLights];  // per list entry: distance to its adjusted sphere, < 0 when eliminated
float od_[kSlMaxLights];   // per list entry: distance of its object's centre (per-object blocking)
uint lb_;                  // the first entry of this receiver's list: the arrays are indexed from it

// Section 7.2 with the index as the last key: whether SL a comes before SL b at P (a total order,
// the CPU's stable sort of the SLs in index order).
bool before(uint a, uint b) {
  if (BLOCKING == kSlPerObject) {
    const float da = od_[a - lb_], db = od_[b - lb_];
    if (da != db) return da < db;
    const uint oa = texel1(object, a), ob = texel1(object, b);
    if (oa != ob) return oa < ob;
  }
  const float ka = key_[a - lb_], kb = key_[b - lb_];
  if (ka != kb) return ka < kb;
  return a < b;
}

// Loop iterations, as llvmpipe counts them, of the loops below (upper bounds): sh_exp with s
// squarings (the norm, the OL search, the start vector, then per squaring its copy; the squares
// are written out), one sphere's log vector or average radiance (the basis recurrence and the
// bands), and the fixed loops of one SL's pair.
uint cost_exp(int s) { return 2u * N * N + 16u + uint(s) * (2u * N * N); }
uint cost_sphere() { return 4u * N * N + 16u; }
uint cost_pair_fixed() { return 6u * N * N + 3u * cost_sphere(); }

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint n2 = N * N, sbase = i * (n2 + 4u);
  uint last = kSlStateNone;
  if (pc.resume != 0u) {
    last = floatBitsToUint(state[sbase + n2 + 3u]);
    if (last == kSlStateDone) return;
  }
  const vec3 P = vec3(texel1(rec, i), texel1(rec, pc.count + i), texel1(rec, 2 * pc.count + i));
  const vec3 Nrm = vec3(texel1(rec, 3 * pc.count + i), texel1(rec, 4 * pc.count + i), texel1(rec, 5 * pc.count + i));
  if (!(dot(Nrm, Nrm) > 0.0)) {
    outv[i] = vec4(0.0);
    state[sbase + n2 + 3u] = uintBitsToFloat(kSlStateDone);
    return;
  }
  float hn[kAccumMaxCoeffs];
  sh_basis_eval(Nrm, hn);
  [[unroll]] for (uint q = 0; q < N * N; ++q) hn[q] *= hcoef(kShBand[q]);
  // The active SLs' order keys and their distances from p.
  const uvec2 list = texelFetch(lists, int(texelFetch(rlist, int(i)).x)).xy;
  lb_ = list.x;
  uint eliminated = 0;
  for (uint k = list.x; k < list.x + list.y; ++k) {
    const vec4 adj = sl_adjusted(k, P, Nrm);
    if (adj.w > 0.0) {
      key_[k - lb_] = length(adj.xyz - P) - adj.w;
    } else {
      key_[k - lb_] = -1.0;
      ++eliminated;
    }
    if (BLOCKING == kSlPerObject) od_[k - lb_] = length(texelFetch(object_centre, int(texelFetch(object, int(k)).x)).xyz - P);
  }
  const uint list_max = subgroupMax(list.y);
  uint used = cost_sphere() + list_max * 8u;
  float prefix[kAccumMaxCoeffs], S[kAccumMaxCoeffs], G[kAccumMaxCoeffs], e0[kAccumMaxCoeffs], SG[kAccumMaxCoeffs];
  vec3 acc = vec3(0.0);
  if (pc.resume == 0u) {
    [[unroll]] for (uint q = 0; q < n2; ++q) prefix[q] = 0.0;
    atomicAdd(status[kSlStatusEliminated], eliminated);
  } else {
    [[unroll]] for (uint q = 0; q < n2; ++q) prefix[q] = state[sbase + q];
    acc = vec3(state[sbase + n2], state[sbase + n2 + 1u], state[sbase + n2 + 2u]);
  }
  uint pairs = 0, clamped = 0;
  bool finished = false, failed = false;
  for (;;) {
    // The next SL in blocking order: the smallest after the last one summed.
    uint k = kSlStateNone;
    for (uint e = list.x; e < list.x + list.y; ++e) {
      if (key_[e - lb_] < 0.0) continue;
      if (last != kSlStateNone && !before(last, e)) continue;
      if (k == kSlStateNone || before(e, k)) k = e;
    }
    used += list_max;
    if (k == kSlStateNone) {
      finished = true;
      break;
    }
    // Eq. 21: S_k, the G of the SLs before k less those of its own object that intersect it.
    [[unroll]] for (uint q = 0; q < n2; ++q) S[q] = prefix[q];
    for (uint t = texel1(inter_begin, k); t < texel1(inter_begin, k + 1); ++t) {
      const uint j = texel1(inter_list, t);
      if (key_[j - lb_] >= 0.0 && before(j, k)) {
        sl_log_vector(sl_adjusted(j, P, Nrm), P, G);
        [[unroll]] for (uint q = 0; q < n2; ++q) S[q] -= G[q];
      }
    }
    sl_log_vector(sl_adjusted(k, P, Nrm), P, G);
    float n0 = 0.0, n1 = 0.0;
    for (uint q = 1; q < n2; ++q) {
      SG[q] = S[q] + G[q];
      n0 += S[q] * S[q];
      n1 += SG[q] * SG[q];
    }
    SG[0] = S[0] + G[0];
    const uint cost = cost_pair_fixed() + subgroupMax(texel1(inter_begin, k + 1) - texel1(inter_begin, k)) * cost_sphere() +
                      cost_exp(subgroupMax(sh_exp_squarings(sqrt(n0), METHOD))) + cost_exp(subgroupMax(sh_exp_squarings(sqrt(n1), METHOD)));
    if (pc.budget != 0xffffffffu) {
      if (cost + 2u * list_max + cost_sphere() > pc.budget) atomicMin(status[kSlStatusBudget], i + 1);
      if (pairs > 0u && used + cost + list_max > pc.budget) break;  // resumed in the next pass
    }
    used += cost;
    int s;
    uint code = sh_exp(S, METHOD, pc.ol_count, 0u, s);
    [[unroll]] for (uint q = 0; q < n2; ++q) e0[q] = exp_g[q];
    if (code == kShExpOk) code = sh_exp(SG, METHOD, pc.ol_count, 0u, s);
    if (code != kShExpOk) {
      atomicMin(status[code == kShExpBadInput ? kSlStatusBadInput : kSlStatusDcOverflow], i + 1);
      failed = true;
      break;
    }
    // Eq. 23: V = exp(S) - exp(S + G), the part of the SL's cap no closer SL covers; eq. 24: dotted
    // with the BRDF vector.
    float v = 0.0;
    bool finite = true;
    [[unroll]] for (uint q = 0; q < n2; ++q) {
      finite = finite && !isinf(e0[q]) && !isnan(e0[q]) && !isinf(exp_g[q]) && !isnan(exp_g[q]);
      v += (e0[q] - exp_g[q]) * hn[q];
      prefix[q] += G[q];
    }
    if (!finite) atomicMin(status[kSlStatusOverflow], i + 1);
    if (v < 0.0) {
      v = 0.0;  // SH ringing of the two exponentials; a visibility is never negative
      ++clamped;
    }
    acc += sl_average_radiance(k, P) * v;
    last = k;
    ++pairs;
  }
  atomicAdd(status[kSlStatusPairs], pairs);
  atomicAdd(status[kSlStatusClamped], clamped);
  if (failed || finished) {
    outv[i] = failed ? vec4(0.0) : vec4(max(acc, vec3(0.0)), 0.0);
    state[sbase + n2 + 3u] = uintBitsToFloat(kSlStateDone);
    return;
  }
  [[unroll]] for (uint q = 0; q < n2; ++q) state[sbase + q] = prefix[q];
  state[sbase + n2] = acc.x;
  state[sbase + n2 + 1u] = acc.y;
  state[sbase + n2 + 2u] = acc.z;
  state[sbase + n2 + 3u] = uintBitsToFloat(last);
  atomicAdd(status[kSlStatusUnfinished], 1u);
}
