// The SH exponential of a log vector (paper 004 section 4) with the rules of the CPU's exp_batch
// (techniques/common/batch_body.hpp exp_block), for every shader that exponentiates:
// shaders/common/exponentiate.comp (one vector per receiver) and shaders/spherical_lights/
// accumulate_indirect.comp (two per receiver and light, paper 001 eq. 23).
// - HYB: optimal linear approximation of the scaled vector, then squarings (eqs. 21-23); OL: the
//   same without squaring. DC isolation, squaring count s = paper_squarings(||f^||) (||f^||/2^s in
//   [1/8, 1/4)), the DC factor applied before the squarings, OL a, b from the core's table by
//   ||f^||/2^s.
// - With SH_EXP_SERIES defined: also PS*-p, the factored series (eq. 22) of the scaled, DC-free
//   vector -- even powers x^2 = x*x, x^4 = x^2*x^2, x^6 = x^4*x^2, ..., the odd part as
//   x * (sum of h_k x^(k-1)) -- times the DC factor, then the same squarings; and PS-p, the plain
//   product series (eq. 17) of the whole f, term_k = term_(k-1) * f / k.
// Products and squares follow ProductPlan (the core's triple-product tensor grouped by output) as
// code generated at build time; the OL table and series coefficients are the CPU's floats, uploaded.
//
// Expects softgi_shared.h included, the shader compiled for one order (SH_PLAN_FIXED_ORDER, cmake's
// ORDER_VARIANTS) and, before this file: SH_EXP_N (the order, a specialisation constant that the
// host sets to SH_PLAN_FIXED_ORDER), SH_EXP_BIND_OL; with SH_EXP_SERIES also SH_EXP_BIND_SERIES.
#ifndef SOFTGI_SH_EXP_GLSL
#define SOFTGI_SH_EXP_GLSL

#if defined(SH_EXP_SERIES) && !defined(SH_EXP_PRODUCTS)
#define SH_EXP_PRODUCTS
#endif

// Tables through texel buffers: a SIMD device fetches texels for all lanes at once, where it reads a
// storage buffer lane by lane with a bounds check per component (llvmpipe).
layout(set = 0, binding = SH_EXP_BIND_OL) uniform samplerBuffer ol;  // norms, a, b (ol_count each)
// The squares are code: sh_square_unrolled.glsl, generated at build time from the CPU's ProductPlan
// (shaders/gen/sh_plan_glsl.cpp), every term written out with constant indices.
#include "sh_square_unrolled.glsl"
#ifdef SH_EXP_PRODUCTS
#include "sh_plan_products.glsl"
#endif
#ifdef SH_EXP_SERIES
layout(set = 0, binding = SH_EXP_BIND_SERIES) uniform samplerBuffer series;
#endif

const float kSqrt4Pi = 3.5449077018110318;

// What sh_exp reports (the CPU's exp_batch throws for the first two).
const uint kShExpOk = 0u;
const uint kShExpBadInput = 1u;    // a non-finite input coefficient
const uint kShExpDcOverflow = 2u;  // the DC factor exp(f_0 / sqrt(4 pi) / 2^s) overflowed

// The result of sh_exp and its scratch vector.
float exp_g[kAccumMaxCoeffs], exp_t[kAccumMaxCoeffs];

// o = a * a (eq. 3 with f = g = a): the generated code for the shader's order.
void sh_square(in float a[kAccumMaxCoeffs], out float o[kAccumMaxCoeffs]) { sh_square_fixed(a, o); }

#ifdef SH_EXP_PRODUCTS
// o = a * b (eq. 3), generated code (sh_plan_products.glsl).
void sh_product(in float a[kAccumMaxCoeffs], in float b[kAccumMaxCoeffs], out float o[kAccumMaxCoeffs]) { sh_product_fixed(a, b, o); }
#endif

void sh_exp_square_g() {
  sh_square(exp_g, exp_t);
  for (uint i = 0; i < SH_EXP_N * SH_EXP_N; ++i) exp_g[i] = exp_t[i];
}

// sh::ShTables::ol_lookup: piecewise linear in the increasing prefix of the OL sweep (eq. 23);
// m = ol_count knots.
void sh_exp_ol_lookup(float norm, uint m, out float a, out float b) {
  if (!(norm > texelFetch(ol, int(0)).x)) {
    a = texelFetch(ol, int(m)).x;
    b = texelFetch(ol, int(2 * m)).x;
    return;
  }
  if (norm >= texelFetch(ol, int(m - 1)).x) {
    a = texelFetch(ol, int(2 * m - 1)).x;
    b = texelFetch(ol, int(3 * m - 1)).x;
    return;
  }
  uint lo = 0, hi = m - 1;  // ol[lo] < norm <= ... < ol[hi]: find the last knot <= norm
  while (hi - lo > 1) {
    const uint mid = (lo + hi) / 2;
    if (texelFetch(ol, int(mid)).x <= norm) lo = mid;
    else hi = mid;
  }
  const float w = (norm - texelFetch(ol, int(lo)).x) / (texelFetch(ol, int(lo + 1)).x - texelFetch(ol, int(lo)).x);
  a = texelFetch(ol, int(m + lo)).x + w * (texelFetch(ol, int(m + lo + 1)).x - texelFetch(ol, int(m + lo)).x);
  b = texelFetch(ol, int(2 * m + lo)).x + w * (texelFetch(ol, int(2 * m + lo + 1)).x - texelFetch(ol, int(2 * m + lo)).x);
}

// The squarings sh_exp does for a vector whose non-DC part has norm `norm` (sh::paper_squarings:
// ||f^|| / 2^s in [1/8, 1/4)); 0 for the methods that do not square.
int sh_exp_squarings(float norm, uint method) {
  if ((method == kExpHyb || method == kExpPsStar) && norm > 0.0 && !isinf(norm)) {
    int e;
    frexp(norm, e);  // floor(log2 norm) = e - 1
    return max(0, e + 2);
  }
  return 0;
}

// exp_g = exp*(f) by `method` (kExp*; PS* and PS only with SH_EXP_SERIES), `s` the squarings done.
// ol_count: knots of the OL table; degree: the series degree p (PS*, PS). Returns kShExpOk, or
// kShExpBadInput / kShExpDcOverflow with exp_g unset. Overflow of the result is the caller's check.
uint sh_exp(in float f[kAccumMaxCoeffs], uint method, uint ol_count, uint degree, out int s) {
  const uint n2 = SH_EXP_N * SH_EXP_N;
  s = 0;
  float norm2 = 0.0;
  bool finite = true;
  for (uint k = 0; k < n2; ++k) {
    const float v = f[k];
    finite = finite && !isnan(v) && !isinf(v);
    if (k > 0) norm2 += v * v;
  }
  if (!finite) return kShExpBadInput;
  const float norm = sqrt(norm2);
  s = sh_exp_squarings(norm, method);
  const float scale = ldexp(1.0, -s);
  const float dc = exp(f[0] / kSqrt4Pi * scale);
  if (isinf(dc)) return kShExpDcOverflow;
  if (method == kExpHyb || method == kExpOl) {
    float a, b;
    sh_exp_ol_lookup(norm * scale, ol_count, a, b);
    // g = a 1 + b f^/2^s, times the DC factor (eq. 23).
    exp_g[0] = (a * kSqrt4Pi) * dc;
    for (uint k = 1; k < n2; ++k) exp_g[k] = (b * (f[k] * scale)) * dc;
  }
#ifdef SH_EXP_SERIES
  else if (method == kExpPsStar) {
    // Eq. 22 on x = f^/2^s: even = 1 + sum_even h_k x^k, odd = 1 + sum_odd h_k x^(k-1).
    float x[kAccumMaxCoeffs], x2[kAccumMaxCoeffs], pw[kAccumMaxCoeffs], odd[kAccumMaxCoeffs];
    for (uint k = 0; k < n2; ++k) {
      x[k] = k == 0 ? 0.0 : f[k] * scale;
      exp_g[k] = odd[k] = k == 0 ? kSqrt4Pi : 0.0;  // exp_g holds the even part
      x2[k] = pw[k] = 0.0;
    }
    for (uint k = 2; k <= degree; ++k) {
      const float h = texelFetch(series, int(k)).x;
      if (k % 2 == 0) {
        if (k == 2) {
          sh_square(x, x2);
          for (uint c = 0; c < n2; ++c) pw[c] = x2[c];
        } else if (k == 4) {
          sh_square(x2, exp_t);
          for (uint c = 0; c < n2; ++c) pw[c] = exp_t[c];
        } else {
          sh_product(pw, x2, exp_t);
          for (uint c = 0; c < n2; ++c) pw[c] = exp_t[c];
        }
        for (uint c = 0; c < n2; ++c) exp_g[c] = h * pw[c] + exp_g[c];
      } else {
        for (uint c = 0; c < n2; ++c) odd[c] = h * pw[c] + odd[c];
      }
    }
    if (degree >= 3) {
      sh_product(x, odd, exp_t);
      for (uint c = 0; c < n2; ++c) exp_g[c] += exp_t[c];
    } else {
      for (uint c = 0; c < n2; ++c) exp_g[c] += x[c];
    }
    for (uint c = 0; c < n2; ++c) exp_g[c] *= dc;
  } else {
    // PS: g = 1 + f + sum_(k >= 2) f^k / k! on the whole f, powers left to right.
    float x[kAccumMaxCoeffs], term[kAccumMaxCoeffs];
    for (uint k = 0; k < n2; ++k) {
      x[k] = term[k] = f[k];
      exp_g[k] = (k == 0 ? kSqrt4Pi : 0.0) + x[k];
    }
    for (uint k = 2; k <= degree; ++k) {
      sh_product(term, x, exp_t);
      const float inv = texelFetch(series, int(k)).x;
      for (uint c = 0; c < n2; ++c) {
        term[c] = exp_t[c] * inv;
        exp_g[c] += term[c];
      }
    }
  }
#endif
  for (int it = 0; it < s; ++it) sh_exp_square_g();  // eq. 21
  return kShExpOk;
}

#endif
