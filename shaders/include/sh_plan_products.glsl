// ProductPlan products (the core's triple-product tensor grouped by output, eq. 3) as the shaders
// read them: two uniform buffers (softgi_shared.h kPlanPr*), for the reason sh_exp.glsl gives for the
// squares: every lane reads the same term at the same time, which a uniform buffer serves in one
// vector load where llvmpipe loads a storage buffer lane by lane. std140 pads array elements to 16
// bytes, so the words travel as uvec4s.
// Expects softgi_shared.h included and SH_PLAN_PR_BIND_INDEX, SH_PLAN_PR_BIND_TERMS defined.
#ifndef SOFTGI_SH_PLAN_PRODUCTS_GLSL
#define SOFTGI_SH_PLAN_PRODUCTS_GLSL

layout(std140, set = 0, binding = SH_PLAN_PR_BIND_INDEX) uniform ShPlanPrIndex { uvec4 pr_range4[kPlanPrIndexMax / 4u]; };
layout(std140, set = 0, binding = SH_PLAN_PR_BIND_TERMS) uniform ShPlanPrTerms {
  uvec4 pr_jk4[kPlanPrTermsMax / 4u];  // j | k << 16
  uvec4 pr_v4[kPlanPrTermsMax / 4u];   // v bits
};

// Output i's terms: [x, y) off-diagonal (j < k), [y, pr_range_at(i + 1).x) diagonal.
uvec2 pr_range_at(uint i) {
  const uint w = 2u * i;
  return uvec2(pr_range4[w >> 2u][w & 3u], pr_range4[(w + 1u) >> 2u][(w + 1u) & 3u]);
}
uint pr_j_at(uint q) { return pr_jk4[q >> 2u][q & 3u] & 0xffffu; }
uint pr_k_at(uint q) { return pr_jk4[q >> 2u][q & 3u] >> 16; }
float pr_v_at(uint q) { return uintBitsToFloat(pr_v4[q >> 2u][q & 3u]); }

#endif
