#version 450
// SHEXP exponential of the accumulated log vector (paper 004 section 4), one invocation per
// receiver, with the rules of the CPU's exp_batch (techniques/common/batch_body.hpp exp_block):
// - HYB: optimal linear approximation of the scaled vector, then squarings (eqs. 21-23); OL: the
//   same without squaring. DC isolation, squaring count s = paper_squarings(||f^||) (||f^||/2^s in
//   [1/8, 1/4)), the DC factor applied before the squarings, OL a, b from the core's table by
//   ||f^||/2^s.
// - PS*-p: the factored series (eq. 22) of the scaled, DC-free vector -- even powers x^2 = x*x,
//   x^4 = x^2*x^2, x^6 = x^4*x^2, ..., the odd part as x * (sum of h_k x^(k-1)) -- times the DC
//   factor, then the same squarings.
// - PS-p: the plain product series (eq. 17) of the whole f, term_k = term_(k-1) * f / k.
// Products and squares follow shexp::ProductPlan (the core's triple-product tensor grouped by
// output), the series coefficients are the CPU's floats; all uploaded.
#extension GL_GOOGLE_include_directive : require
#include "softgi_shared.h"

layout(constant_id = 0) const uint N = 4;       // accumulation order
layout(constant_id = 1) const uint NOUT = 4;    // shading order (the result is truncated to it)
layout(constant_id = 2) const uint METHOD = kExpHyb;
layout(local_size_x = kExponentiateGroup) in;

layout(std430, set = 0, binding = kExpBindIn) readonly buffer In { float f_in[]; };
layout(std430, set = 0, binding = kExpBindOut) writeonly buffer Out { float g_out[]; };
layout(std430, set = 0, binding = kExpBindOl) readonly buffer Ol { float ol[]; };  // norms, a, b (ol_count each)
layout(std430, set = 0, binding = kExpBindSqIndex) readonly buffer SqIndex { uint sq_begin[]; };
layout(std430, set = 0, binding = kExpBindSqTerms) readonly buffer SqTerms { uvec2 sq_terms[]; };  // (j | k << 16, v bits)
layout(std430, set = 0, binding = kExpBindStatus) buffer Status { uint status[]; };
layout(std430, set = 0, binding = kExpBindPrIndex) readonly buffer PrIndex { uvec2 pr_range[]; };  // (begin, offdiag_end); end = next begin
layout(std430, set = 0, binding = kExpBindPrTerms) readonly buffer PrTerms { uvec2 pr_terms[]; };
layout(std430, set = 0, binding = kExpBindSeries) readonly buffer Series { float series[]; };
layout(push_constant) uniform Push {
  uint first;     // first receiver of this dispatch
  uint end;       // one past the last
  uint ol_count;  // knots of the OL table
  uint degree;    // series degree p (PS*, PS)
} pc;

const float kSqrt4Pi = 3.5449077018110318;

float g[kAccumMaxCoeffs], t[kAccumMaxCoeffs];

// o = a * a (eq. 3 with f = g = a).
void square(in float a[kAccumMaxCoeffs], out float o[kAccumMaxCoeffs]) {
  for (uint i = 0; i < N * N; ++i) {
    float acc = 0.0;
    for (uint q = sq_begin[i]; q < sq_begin[i + 1]; ++q) {
      const uvec2 term = sq_terms[q];
      acc += uintBitsToFloat(term.y) * (a[term.x & 0xffffu] * a[term.x >> 16]);
    }
    o[i] = acc;
  }
}

// o = a * b (eq. 3): off-diagonal terms v (a_j b_k + a_k b_j), then diagonal v a_j b_j.
void product(in float a[kAccumMaxCoeffs], in float b[kAccumMaxCoeffs], out float o[kAccumMaxCoeffs]) {
  for (uint i = 0; i < N * N; ++i) {
    const uvec2 rg = pr_range[i];
    const uint end = pr_range[i + 1].x;
    float acc = 0.0;
    for (uint q = rg.x; q < rg.y; ++q) {
      const uvec2 term = pr_terms[q];
      const uint j = term.x & 0xffffu, k = term.x >> 16;
      acc += uintBitsToFloat(term.y) * (a[j] * b[k] + a[k] * b[j]);
    }
    for (uint q = rg.y; q < end; ++q) {
      const uvec2 term = pr_terms[q];
      const uint j = term.x & 0xffffu;
      acc += uintBitsToFloat(term.y) * (a[j] * b[j]);
    }
    o[i] = acc;
  }
}

void square_g() {
  square(g, t);
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
  if ((METHOD == kExpHyb || METHOD == kExpPsStar) && norm > 0.0 && !isinf(norm)) {
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
  if (METHOD == kExpHyb || METHOD == kExpOl) {
    float a, b;
    ol_lookup(norm * scale, a, b);
    // g = a 1 + b f^/2^s, times the DC factor (eq. 23).
    g[0] = (a * kSqrt4Pi) * dc;
    for (uint k = 1; k < n2; ++k) g[k] = (b * (f_in[base + k] * scale)) * dc;
  } else if (METHOD == kExpPsStar) {
    // Eq. 22 on x = f^/2^s: even = 1 + sum_even h_k x^k, odd = 1 + sum_odd h_k x^(k-1).
    float x[kAccumMaxCoeffs], x2[kAccumMaxCoeffs], pw[kAccumMaxCoeffs], odd[kAccumMaxCoeffs];
    for (uint k = 0; k < n2; ++k) {
      x[k] = k == 0 ? 0.0 : f_in[base + k] * scale;
      g[k] = odd[k] = k == 0 ? kSqrt4Pi : 0.0;  // g holds the even part
      x2[k] = pw[k] = 0.0;
    }
    for (uint k = 2; k <= pc.degree; ++k) {
      const float h = series[k];
      if (k % 2 == 0) {
        if (k == 2) {
          square(x, x2);
          for (uint c = 0; c < n2; ++c) pw[c] = x2[c];
        } else if (k == 4) {
          square(x2, t);
          for (uint c = 0; c < n2; ++c) pw[c] = t[c];
        } else {
          product(pw, x2, t);
          for (uint c = 0; c < n2; ++c) pw[c] = t[c];
        }
        for (uint c = 0; c < n2; ++c) g[c] = h * pw[c] + g[c];
      } else {
        for (uint c = 0; c < n2; ++c) odd[c] = h * pw[c] + odd[c];
      }
    }
    if (pc.degree >= 3) {
      product(x, odd, t);
      for (uint c = 0; c < n2; ++c) g[c] += t[c];
    } else {
      for (uint c = 0; c < n2; ++c) g[c] += x[c];
    }
    for (uint c = 0; c < n2; ++c) g[c] *= dc;
  } else {
    // PS: g = 1 + f + sum_(k >= 2) f^k / k! on the whole f, powers left to right.
    float x[kAccumMaxCoeffs], term[kAccumMaxCoeffs];
    for (uint k = 0; k < n2; ++k) {
      x[k] = term[k] = f_in[base + k];
      g[k] = (k == 0 ? kSqrt4Pi : 0.0) + x[k];
    }
    for (uint k = 2; k <= pc.degree; ++k) {
      product(term, x, t);
      const float inv = series[k];
      for (uint c = 0; c < n2; ++c) {
        term[c] = t[c] * inv;
        g[c] += term[c];
      }
    }
  }
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
