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
#include "accum_log_pair.glsl"
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
    vec3 sh_dir;
    float fl[kAccumMaxOrder];
    if (!accum_log_pair(texelFetch(blockers, int(b)), b, P, Nrm, pc.cut, pc.scale, pc.rows, sh_dir, fl)) continue;
    // Basis by recurrence, accumulated as in kernel_block (SH_BASIS_PUT: accum_log_pair.glsl).
    { SH_BASIS_UNROLLED(N) }
  }
  [[unroll]] for (uint c = 0; c < N * N; ++c) imageStore(outv, int(i * N * N + c), vec4(acc[c]));
}
