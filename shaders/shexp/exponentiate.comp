#version 450
// SHEXP exponential of the accumulated log vector (paper 004 section 4.3), one invocation per
// receiver: HYB (optimal linear approximation of the scaled vector, then squarings, eqs. 21-23) or
// OL (no squaring), with the rules of sh::exp_hyb / the CPU's exp_batch: DC isolation, squaring count
// s = paper_squarings(||f^||) (||f^||/2^s in [1/8, 1/4)), the DC factor applied before the
// squarings, OL a, b from the core's table by ||f^||/2^s. Products follow shexp::ProductPlan
// (the core's triple-product tensor grouped by output), uploaded.
#extension GL_GOOGLE_include_directive : require
#include "softgi_shared.h"

layout(constant_id = 0) const uint N = 4;       // accumulation order
layout(constant_id = 1) const uint NOUT = 4;    // shading order (the result is truncated to it)
layout(constant_id = 2) const uint METHOD = kExpHyb;
layout(local_size_x = kShexpExpGroup) in;

layout(std430, set = 0, binding = kExpBindIn) readonly buffer In { float f_in[]; };
layout(std430, set = 0, binding = kExpBindOut) writeonly buffer Out { float g_out[]; };
layout(std430, set = 0, binding = kExpBindOl) readonly buffer Ol { float ol[]; };  // norms, a, b (ol_count each)
layout(std430, set = 0, binding = kExpBindSqIndex) readonly buffer SqIndex { uint sq_begin[]; };
layout(std430, set = 0, binding = kExpBindSqTerms) readonly buffer SqTerms { uvec2 sq_terms[]; };  // (j | k << 16, v bits)
layout(std430, set = 0, binding = kExpBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  uint first;     // first receiver of this dispatch
  uint end;       // one past the last
  uint ol_count;  // knots of the OL table
} pc;

const float kSqrt4Pi = 3.5449077018110318;

float g[kShexpMaxCoeffs], t[kShexpMaxCoeffs];

// t = g * g (eq. 3 with f = g).
void square_g() {
  for (uint i = 0; i < N * N; ++i) {
    float acc = 0.0;
    for (uint q = sq_begin[i]; q < sq_begin[i + 1]; ++q) {
      const uvec2 term = sq_terms[q];
      acc += uintBitsToFloat(term.y) * (g[term.x & 0xffffu] * g[term.x >> 16]);
    }
    t[i] = acc;
  }
  for (uint i = 0; i < N * N; ++i) g[i] = t[i];
}

// sh::ShTables::ol_lookup: piecewise linear in the increasing prefix of the OL sweep (eq. 23).
void ol_lookup(float norm, out float a, out float b) {
  const uint m = pc.ol_count;
  if (!(norm > ol[0])) {
    a = ol[m];
    b = ol[2 * m];
    return;
  }
  if (norm >= ol[m - 1]) {
    a = ol[2 * m - 1];
    b = ol[3 * m - 1];
    return;
  }
  uint lo = 0, hi = m - 1;  // ol[lo] < norm <= ... < ol[hi]: find the last knot <= norm
  while (hi - lo > 1) {
    const uint mid = (lo + hi) / 2;
    if (ol[mid] <= norm) lo = mid;
    else hi = mid;
  }
  const float w = (norm - ol[lo]) / (ol[lo + 1] - ol[lo]);
  a = ol[m + lo] + w * (ol[m + lo + 1] - ol[m + lo]);
  b = ol[2 * m + lo] + w * (ol[2 * m + lo + 1] - ol[2 * m + lo]);
}

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint n2 = N * N, base = i * n2;
  float norm2 = 0.0;
  bool finite = true;
  for (uint k = 0; k < n2; ++k) {
    const float v = f_in[base + k];
    finite = finite && !isnan(v) && !isinf(v);
    if (k > 0) norm2 += v * v;
  }
  if (!finite) {
    atomicMin(status[kExpStatusBadInput], i + 1);
    return;
  }
  const float norm = sqrt(norm2);
  int s = 0;
  if (METHOD == kExpHyb && norm > 0.0 && !isinf(norm)) {
    int e;
    frexp(norm, e);  // floor(log2 norm) = e - 1 (sh::paper_squarings)
    s = max(0, e + 2);
  }
  const float scale = ldexp(1.0, -s);
  const float dc = exp(f_in[base] / kSqrt4Pi * scale);
  if (isinf(dc)) {
    atomicMin(status[kExpStatusDcOverflow], i + 1);
    return;
  }
  float a, b;
  ol_lookup(norm * scale, a, b);
  // g = a 1 + b f^/2^s, times the DC factor (eq. 23).
  g[0] = (a * kSqrt4Pi) * dc;
  for (uint k = 1; k < n2; ++k) g[k] = (b * (f_in[base + k] * scale)) * dc;
  for (int it = 0; it < s; ++it) square_g();  // eq. 21
  bool ok = true;
  for (uint k = 0; k < NOUT * NOUT; ++k) {
    ok = ok && !isnan(g[k]) && !isinf(g[k]);
    g_out[i * NOUT * NOUT + k] = g[k];
  }
  for (uint k = NOUT * NOUT; k < n2; ++k) ok = ok && !isnan(g[k]) && !isinf(g[k]);
  if (!ok) atomicMin(status[kExpStatusOverflow], i + 1);
  atomicAdd(status[kExpStatusSquarings], uint(s));
}
