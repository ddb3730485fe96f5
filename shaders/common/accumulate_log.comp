#version 450
// SHEXP log-visibility accumulation (paper 004 eqs. 8, 34, 38) with the self-shadowing replacement
// rules of section 6.2: one invocation per receiver, summing W_b F(theta_b) y(s_b) over the blocker
// list of its receiver cluster. The arithmetic follows the CPU kernel (techniques/shexp/
// kernel_body.hpp, blocker_view and kernel_block) step by step; the tables and basis constants are
// the CPU's own floats, uploaded.
#extension GL_GOOGLE_include_directive : require
// [[unroll]] on the loops over bands and coefficients: their trip counts are the specialisation
// constant N, so after specialisation the driver unrolls them and keeps acc[] in registers.
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#define SHEXP_BASIS_BINDING kAccBindBasis
#include "sh_basis.glsl"
#include "accum_math.glsl"

layout(constant_id = 0) const uint N = 4;           // accumulation order
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(local_size_x = kAccumulateGroup) in;

layout(std430, set = 0, binding = kAccBindReceivers) readonly buffer Receivers { float rec[]; };
layout(std430, set = 0, binding = kAccBindReceiverList) readonly buffer ReceiverList { uint rlist[]; };
layout(std430, set = 0, binding = kAccBindListRange) readonly buffer ListRange { uvec2 ranges[]; };
layout(std430, set = 0, binding = kAccBindBlockers) readonly buffer Blockers { vec4 blockers[]; };
layout(std430, set = 0, binding = kAccBindWeights) readonly buffer Weights { float weights[]; };
layout(std430, set = 0, binding = kAccBindTable) readonly buffer Table { float table[]; };
layout(std430, set = 0, binding = kAccBindOut) buffer Out { float outv[]; };
layout(push_constant) uniform Push {
  uint count;       // receivers in all (the planes of rec are this long)
  uint first;       // first receiver of this dispatch
  uint end;         // one past the last receiver of this dispatch
  uint rows;        // table rows
  float scale;      // table: (rows - 1) / (pi/2)
  float cut;        // > 0: a blocker counts only where |c - p| < cut r, before the rules (image_splat's
                    // per-pair sphere-of-influence cut, paper 000 section 4.1); 0: every blocker
  uint chunk_first; // this dispatch sums blockers [chunk_first, chunk_first + chunk_count) of each list
  uint chunk_count; // (a driver's loop-iteration limit caps what one invocation may loop over)
  uint chunk_add;   // 1: add to the sums of the chunks before (read back from outv); 0: the first chunk
} pc;

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const vec3 P = vec3(rec[i], rec[pc.count + i], rec[2 * pc.count + i]);
  const vec3 Nrm = vec3(rec[3 * pc.count + i], rec[4 * pc.count + i], rec[5 * pc.count + i]);
  const uvec2 range = ranges[rlist[i]];
  if (pc.chunk_add != 0u && pc.chunk_first >= range.y) return;  // this list ended in an earlier chunk
  float acc[kAccumMaxCoeffs];
  [[unroll]] for (uint c = 0; c < N * N; ++c) acc[c] = pc.chunk_add != 0u ? outv[i * N * N + c] : 0.0;
  const uint b_end = range.x + min(range.y, pc.chunk_first + pc.chunk_count);
  for (uint b = range.x + pc.chunk_first; b < b_end; ++b) {
    const vec4 sphere = blockers[b];
    const float r = sphere.w;
    const vec3 d = sphere.xyz - P;
    if (pc.cut > 0.0 && !(length(d) < pc.cut * r)) continue;  // image_splat_core.cpp accumulate_log_range
    const float h = dot(d, Nrm);  // centre height above the tangent plane T_p
    const float d2 = dot(d, d);
    const float a2 = max(d2 - h * h, 0.0);  // squared in-plane distance from p to q1
    // Replacement rules (section 6.2; techniques/common/accumulation.hpp): a sphere tangent to T_p at q1, radius rho.
    float rho = r, hh = h;
    if (RULE != kRuleOff && h < r) {
      const float r2 = r * r;
      const bool inside = d2 < r2;
      const float rin = max(h, 0.0);
      const float rout = max(0.5 * (h + r), 0.0);
      const float dmin = 1e-6 * r;
      const float q = max(r2 - h * h, 0.0);
      const float rq = inversesqrt(max(q, 1e-12 * r * r));
      const float dd = q * rq;
      const float dist = a2 * inversesqrt(max(a2, 1e-30));
      const float ratio = (dist - dd) * rq;
      if (RULE == kRuleContinuous) {
        const float t = inside ? 0.0 : clamp(ratio, 0.0, 1.0);
        rho = t * (rout - rin) + rin;
      } else if (RULE == kRuleClamped) {
        const float t = clamp(ratio, 0.0, 1.0);
        rho = inside ? rin : t * rout;
      } else if (RULE == kRuleInsideOnly) {
        rho = inside ? rin : r;  // outside: the sphere whole (below, hh stays h)
      } else {
        const float a = dmin < dd ? max(ratio, 1.0) : 1.0;
        rho = inside ? rin : a * rout;
      }
      hh = (RULE == kRuleInsideOnly && !inside) ? h : rho;
    }
    const vec3 v = d + (hh - h) * Nrm;
    const float inv = inversesqrt(max(dot(v, v), 1e-30));
    const float st = (1e-6 * r < rho) ? min(rho * inv, 1.0) : 0.0;
    const float theta = st > 0.0 ? accum_asin01(st) : 0.0;
    const float u = theta * pc.scale;
    const int k = clamp(int(u), 0, int(pc.rows) - 2);
    const float fr = u - float(k);
    const uint row = uint(k) * 2u * N;
    float fl[kAccumMaxOrder];
    [[unroll]] for (uint l = 0; l < N; ++l) fl[l] = (fr * table[row + 2 * l + 1] + table[row + 2 * l]) * weights[b * N + l];  // W of eq. 38
    const vec3 s = v * inv;
    // Basis by recurrence, accumulated as in kernel_block.
    float C[kAccumMaxOrder], S[kAccumMaxOrder];
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
          acc[i0] += fl[l] * qv;
        } else {
          const float g = fl[l] * qv;
          acc[i0 + m] += g * C[m];
          acc[i0 - m] += g * S[m];
        }
      }
    }
  }
  [[unroll]] for (uint c = 0; c < N * N; ++c) outv[i * N * N + c] = acc[c];
}
