// Elementary functions of the shading and accumulation shaders, evaluated by fixed polynomials
// rather than the driver's built-ins: Vulkan bounds asin/acos/sin/cos only loosely (sin, cos: 2^-11
// absolute on [-pi, pi]), so a GPU's results could drift from the CPU's std:: functions by far more
// than a float rounding. Expects sh_basis.glsl included (the asin coefficients are uploaded with
// the basis constants, the CPU kernel's own floats).
#ifndef SOFTGI_SHEXP_MATH_GLSL
#define SOFTGI_SHEXP_MATH_GLSL

const float kAccumHalfPi = 1.57079632679489662;
const float kAccumPi = 3.14159265358979324;

// asin(x) on [0, 1]: Abramowitz & Stegun 4.4.46 in Estrin's form (|error| <= 2e-8), as
// kernel_body.hpp asin01.
float accum_asin01(float x) {
  const float x2 = x * x, x4 = x2 * x2;
  const float p01 = basis_c(kBasisAsin + 1) * x + basis_c(kBasisAsin + 0);
  const float p23 = basis_c(kBasisAsin + 3) * x + basis_c(kBasisAsin + 2);
  const float p45 = basis_c(kBasisAsin + 5) * x + basis_c(kBasisAsin + 4);
  const float p67 = basis_c(kBasisAsin + 7) * x + basis_c(kBasisAsin + 6);
  const float p = (p67 * x2 + p45) * x4 + (p23 * x2 + p01);
  const float omx = max(1.0 - x, 0.0);
  const float s = omx * inversesqrt(max(omx, 1e-30));
  return max(kAccumHalfPi - s * p, 0.0);
}

// acos(x) on [-1, 1] from the same polynomial: acos(x) = pi/2 -+ asin(|x|).
float accum_acos(float x) {
  const float a = accum_asin01(min(abs(x), 1.0));
  return x >= 0.0 ? kAccumHalfPi - a : kAccumHalfPi + a;
}

// sin and cos of a in [0, pi/2] by their Taylor polynomials to degree 13 and 14 (truncation below
// 6e-9 on that range, under a float ulp of the result).
vec2 accum_sincos_quarter(float a) {
  const float a2 = a * a;
  const float s = a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362880.0 +
                  a2 * (-1.0 / 39916800.0 + a2 * (1.0 / 6227020800.0)))))));
  const float c = 1.0 + a2 * (-0.5 + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40320.0 + a2 * (-1.0 / 3628800.0 +
                  a2 * (1.0 / 479001600.0 + a2 * (-1.0 / 87178291200.0)))))));
  return vec2(s, c);
}

// (sin a, cos a) for a in [0, pi] (reflected about pi/2).
vec2 accum_sincos_half(float a) {
  const float r = a <= kAccumHalfPi ? a : kAccumPi - a;
  const vec2 sc = accum_sincos_quarter(clamp(r, 0.0, kAccumHalfPi));
  return a <= kAccumHalfPi ? sc : vec2(sc.x, -sc.y);
}

#endif
