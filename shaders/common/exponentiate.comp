#version 450
// SHEXP exponential of the accumulated log vector (paper 004 section 4), one invocation per
// receiver: HYB, OL, PS*-p and PS-p with the rules of the CPU's exp_batch (techniques/common/
// batch_body.hpp exp_block), shared with the other shaders that exponentiate in
// shaders/include/sh_exp.glsl (which documents the methods).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "softgi_shared.h"

layout(constant_id = 0) const uint N = SH_PLAN_FIXED_ORDER;       // accumulation order
layout(constant_id = 1) const uint NOUT = 4;    // shading order (the result is truncated to it)
layout(constant_id = 2) const uint METHOD = kExpHyb;
layout(local_size_x = kExponentiateGroup) in;

#define SH_EXP_N N
#define SH_EXP_SERIES
#define SH_EXP_BIND_OL kExpBindOl
#define SH_EXP_BIND_SERIES kExpBindSeries
#include "sh_exp.glsl"

layout(set = 0, binding = kExpBindIn) uniform samplerBuffer f_in;
layout(std430, set = 0, binding = kExpBindOut) writeonly buffer Out { float g_out[]; };
layout(std430, set = 0, binding = kExpBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  uint first;     // first receiver of this dispatch
  uint end;       // one past the last
  uint ol_count;  // knots of the OL table
  uint degree;    // series degree p (PS*, PS)
  uint budget;    // loop iterations an invocation may run (0xffffffff: no limit; see below)
} pc;

// Mesa's llvmpipe ends every loop of an invocation once its loops together have iterated 65535
// times (one counter per SIMD batch), which would silently cut the squarings or the series short.
// An upper bound of the batch's iterations (the subgroup's most squarings): the input and output
// loops, the OL search, the series' copies, then the squarings (a copy each; the products and
// squares themselves are written out, no loops).
uint loop_cost(int s) {
  const uint n2 = N * N, step = 2u * n2;
  const uint series = METHOD == kExpPs || METHOD == kExpPsStar ? (pc.degree + 1u) * step : 0u;
  return 5u * n2 + 16u + series + uint(s) * (2u * n2);
}

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint n2 = N * N, base = i * n2;
  float f[kAccumMaxCoeffs];
  for (uint k = 0; k < n2; ++k) f[k] = texelFetch(f_in, int(base + k)).x;
  int s;
  const uint code = sh_exp(f, METHOD, pc.ol_count, pc.degree, s);
  if (pc.budget != 0xffffffffu && loop_cost(subgroupMax(s)) > pc.budget) atomicMin(status[kExpStatusLoopBudget], i + 1);
  if (code == kShExpBadInput) {
    atomicMin(status[kExpStatusBadInput], i + 1);
    return;
  }
  if (code == kShExpDcOverflow) {
    atomicMin(status[kExpStatusDcOverflow], i + 1);
    return;
  }
  bool ok = true;
  for (uint k = 0; k < NOUT * NOUT; ++k) {
    ok = ok && !isnan(exp_g[k]) && !isinf(exp_g[k]);
    g_out[i * NOUT * NOUT + k] = exp_g[k];
  }
  for (uint k = NOUT * NOUT; k < n2; ++k) ok = ok && !isnan(exp_g[k]) && !isinf(exp_g[k]);
  if (!ok) atomicMin(status[kExpStatusOverflow], i + 1);
  atomicAdd(status[kExpStatusSquarings], uint(s));
}
