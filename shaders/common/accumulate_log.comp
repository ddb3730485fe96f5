#version 450
// SHEXP log-visibility accumulation (paper 004 eqs. 8, 34, 38) with the self-shadowing replacement
// rules of section 6.2: one invocation per receiver, summing W_b F(theta_b) y(s_b) over the blocker
// list of its receiver cluster. The arithmetic follows the CPU kernel (techniques/shexp/
// kernel_body.hpp, blocker_view and kernel_block) step by step; the tables and basis constants are
// the CPU's own floats, uploaded.
#extension GL_GOOGLE_include_directive : require
// [[unroll]] on the loops over bands and coefficients: their trip counts are the specialisation
// constant N. The basis steps are written out (SH_BASIS_UNROLLED, sh_basis.glsl) since a driver may
// not unroll them even so, and acc[] stays in registers only where every index is a constant.
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"
#define SHEXP_BASIS_BINDING kAccBindBasis
#include "sh_basis.glsl"
#include "accum_math.glsl"

layout(constant_id = 0) const uint N = 4;           // accumulation order
layout(constant_id = 1) const uint RULE = kRuleContinuous;
layout(local_size_x = kAccumulateGroup) in;
const uint W4 = (N + 3u) / 4u;  // vec4s of band weights per blocker (kAccWeightStride(N) / 4)

layout(set = 0, binding = kAccBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kAccBindReceiverList) uniform usamplerBuffer rlist;
layout(set = 0, binding = kAccBindListRange) uniform usamplerBuffer ranges;
// Every buffer is read and written through texel buffers, the loop's as vectors: the spheres, the
// band weights in rows of kAccWeightStride floats per blocker and the table's (value, slope) pairs.
// A SIMD device fetches texels for all lanes at once, where it reads a storage buffer lane by lane
// with a bounds check per component (llvmpipe).
layout(set = 0, binding = kAccBindBlockers) uniform samplerBuffer blockers;
layout(set = 0, binding = kAccBindWeights) uniform samplerBuffer weights4;
layout(set = 0, binding = kAccBindTable) uniform samplerBuffer table2;
layout(set = 0, binding = kAccBindOut, r32f) uniform imageBuffer outv;
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
  const int n = int(pc.count), ii = int(i);
  const vec3 P = vec3(texelFetch(rec, ii).x, texelFetch(rec, n + ii).x, texelFetch(rec, 2 * n + ii).x);
  const vec3 Nrm = vec3(texelFetch(rec, 3 * n + ii).x, texelFetch(rec, 4 * n + ii).x, texelFetch(rec, 5 * n + ii).x);
  const uvec2 range = texelFetch(ranges, int(texelFetch(rlist, ii).x)).xy;
  if (pc.chunk_add != 0u && pc.chunk_first >= range.y) return;  // this list ended in an earlier chunk
  float acc[kAccumMaxCoeffs];
  [[unroll]] for (uint c = 0; c < N * N; ++c) acc[c] = pc.chunk_add != 0u ? imageLoad(outv, int(i * N * N + c)).x : 0.0;
  const uint b_end = range.x + min(range.y, pc.chunk_first + pc.chunk_count);
  for (uint b = range.x + pc.chunk_first; b < b_end; ++b) {
    const vec4 sphere = texelFetch(blockers, int(b));
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
    const uint row = uint(k) * N;
    float w[4u * ((kAccumMaxOrder + 3u) / 4u)];
    [[unroll]] for (uint q = 0; q < W4; ++q) {
      const vec4 x = texelFetch(weights4, int(b * W4 + q));
      w[4u * q] = x.x;
      w[4u * q + 1u] = x.y;
      w[4u * q + 2u] = x.z;
      w[4u * q + 3u] = x.w;
    }
    float fl[kAccumMaxOrder];
    [[unroll]] for (uint l = 0; l < N; ++l) {
      const vec2 t = texelFetch(table2, int(row + l)).xy;  // (value, slope) of band l
      fl[l] = (fr * t.y + t.x) * w[l];  // W of eq. 38
    }
    // Basis by recurrence, accumulated as in kernel_block.
    {
      const vec3 sh_dir = v * inv;
#define SH_BASIS_PUT(l, m, q)                       \
  if ((m) == 0u) {                                  \
    acc[(l) * (l) + (l)] += fl[l] * (q);            \
  } else {                                          \
    const float g = fl[l] * (q);                    \
    acc[(l) * (l) + (l) + (m)] += g * sh_C[m];      \
    acc[(l) * (l) + (l) - (m)] += g * sh_S[m];      \
  }
      SH_BASIS_UNROLLED(N)
#undef SH_BASIS_PUT
    }
  }
  [[unroll]] for (uint c = 0; c < N * N; ++c) imageStore(outv, int(i * N * N + c), vec4(acc[c]));
}
