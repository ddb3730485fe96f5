#version 450
// SHEXP diffuse shading (paper 004 eq. 9 and section 7), the CPU's shade_batch per receiver:
// E/pi = (H(N) * g) . L per colour channel, H(N)_lm = hcoef_l y_lm(N) (clamped cosine / pi with the
// rotation factor folded in), g windowed per coefficient, one SH product (shexp::ProductPlan) per
// receiver for the three channels. Unshadowed (no visibility) when HAS_VIS is 0: g = sqrt(4 pi) y_00.
#extension GL_GOOGLE_include_directive : require
// [[unroll]]: loops whose trip counts are the specialisation constant N (registers, not scratch).
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#define SHEXP_BASIS_BINDING kShadeBindBasis
#include "shexp_basis.glsl"

layout(constant_id = 0) const uint N = 4;  // shading order
layout(constant_id = 1) const uint HAS_VIS = 1;
layout(local_size_x = kShexpShadeGroup) in;

layout(std430, set = 0, binding = kShadeBindReceivers) readonly buffer Receivers { float rec[]; };
layout(std430, set = 0, binding = kShadeBindVis) readonly buffer Vis { float vis[]; };
layout(std430, set = 0, binding = kShadeBindConsts) readonly buffer Consts { float consts[]; };  // L (3 n^2), hcoef, gwin
layout(std430, set = 0, binding = kShadeBindPrIndex) readonly buffer PrIndex { uvec2 pr_range[]; };  // (begin, offdiag_end); end = next begin
layout(std430, set = 0, binding = kShadeBindPrTerms) readonly buffer PrTerms { uvec2 pr_terms[]; };
layout(std430, set = 0, binding = kShadeBindOut) writeonly buffer Out { vec4 outv[]; };
layout(push_constant) uniform Push {
  uint count;  // receivers in all (the planes of rec are this long)
  uint first;  // first receiver of this dispatch
  uint end;    // one past the last
} pc;

const float kSqrt4Pi = 3.5449077018110318;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint n2 = N * N;
  const vec3 s = vec3(rec[3 * pc.count + i], rec[4 * pc.count + i], rec[5 * pc.count + i]);
  float H[kShexpMaxCoeffs], g[kShexpMaxCoeffs];
  // y(N) by the recurrence of the accumulation kernel (basis_soa of the CPU).
  float C[kShexpMaxOrder], S[kShexpMaxOrder];
  C[0] = 1.0;
  S[0] = 0.0;
  [[unroll]] for (uint m = 1; m < N; ++m) {
    C[m] = C[m - 1] * s.x - S[m - 1] * s.y;
    S[m] = S[m - 1] * s.x + C[m - 1] * s.y;
  }
  [[unroll]] for (uint m = 0; m < N; ++m) {
    float q_prev = 0.0, qv = basis_qmm(m);
    [[unroll]] for (uint l = m; l < N; ++l) {
      if (l == m + 1) {
        q_prev = qv;
        qv = basis_a1(m) * (s.z * qv);
      } else if (l > m + 1) {
        const float next = basis_A(l, m) * (s.z * qv) - basis_B(l, m) * q_prev;
        q_prev = qv;
        qv = next;
      }
      const uint i0 = l * l + l;
      if (m == 0) {
        H[i0] = qv;
      } else {
        H[i0 + m] = qv * C[m];
        H[i0 - m] = qv * S[m];
      }
    }
  }
  [[unroll]] for (uint k = 0; k < n2; ++k) {
    H[k] *= consts[3 * n2 + k];  // hcoef
    const float gk = HAS_VIS != 0 ? vis[i * n2 + k] : (k == 0 ? kSqrt4Pi : 0.0);
    g[k] = gk * consts[4 * n2 + k];  // gwin
  }
  vec3 e = vec3(0.0);
  for (uint k = 0; k < n2; ++k) {
    // (H * g)_k (eq. 3): off-diagonal terms v (H_j g_k + H_k g_j), then diagonal v H_j g_j.
    const uvec2 rg = pr_range[k];
    const uint end = pr_range[k + 1].x;
    float hg = 0.0;
    for (uint q = rg.x; q < rg.y; ++q) {
      const uvec2 term = pr_terms[q];
      const uint j = term.x & 0xffffu, kk = term.x >> 16;
      hg += uintBitsToFloat(term.y) * (H[j] * g[kk] + H[kk] * g[j]);
    }
    for (uint q = rg.y; q < end; ++q) {
      const uvec2 term = pr_terms[q];
      const uint j = term.x & 0xffffu;
      hg += uintBitsToFloat(term.y) * (H[j] * g[j]);
    }
    e += hg * vec3(consts[k], consts[n2 + k], consts[2 * n2 + k]);
  }
  outv[i] = vec4(e, 0.0);
}
