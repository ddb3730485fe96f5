// SH products (eq. 3) for the shaders: sh_plan_product(a, b, o), o = a * b, by
// sh_product_unrolled.glsl, generated at build time from the CPU's ProductPlan (the core's
// triple-product tensor grouped by output; shaders/gen/sh_plan_glsl.cpp): off-diagonal terms
// v (a_j b_k + a_k b_j), then diagonal v a_j b_j, every term written out with constant indices, in
// the plan's order and with its floats. Code rather than a loop over uploaded terms: llvmpipe keeps
// per-invocation arrays in registers only where every index is a constant.
// Expects softgi_shared.h included and the shader compiled for one order (SH_PLAN_FIXED_ORDER,
// cmake's ORDER_VARIANTS), which its order specialisation constant must equal.
#ifndef SOFTGI_SH_PLAN_PRODUCTS_GLSL
#define SOFTGI_SH_PLAN_PRODUCTS_GLSL

#include "sh_product_unrolled.glsl"

void sh_plan_product(in float a[kAccumMaxCoeffs], in float b[kAccumMaxCoeffs], out float o[kAccumMaxCoeffs]) { sh_product_fixed(a, b, o); }

#endif
