#version 450
// Spherical lights' intensity update (paper 001 section 5.2), one invocation per SL and colour
// channel: L_S = sum over the SL's sample points k of L_p[k] Y_k (eq. 10, the 4 pi/N of eq. 9 folded
// into Y_k), then L^c_S = L_S * c_S (eq. 11) by the SH product of ProductPlan (the core's
// triple-product tensor), as pass_intensity in techniques/spherical_lights/spherical_lights.cpp.
#extension GL_GOOGLE_include_directive : require
#include "softgi_shared.h"
#include "sl_shared.h"

layout(constant_id = 0) const uint N = SH_PLAN_FIXED_ORDER;  // SH order
layout(local_size_x = kSlIntensityGroup) in;

layout(std430, set = 0, binding = kSlIntBindRadiance) readonly buffer Radiance { float lp[]; };
layout(std430, set = 0, binding = kSlIntBindRanges) readonly buffer Ranges { uint sample_begin[]; };
layout(std430, set = 0, binding = kSlIntBindBasis) readonly buffer Basis { float basis[]; };
layout(std430, set = 0, binding = kSlIntBindAlbedo) readonly buffer Albedo { float albedo[]; };
#include "sh_plan_products.glsl"
layout(std430, set = 0, binding = kSlIntBindOut) writeonly buffer Out { float outv[]; };
layout(push_constant) uniform Push {
  uint first;  // first (SL, channel) of this dispatch: SL * 3 + channel
  uint end;    // one past the last
} pc;

void main() {
  const uint id = pc.first + gl_GlobalInvocationID.x;
  if (id >= pc.end) return;
  const uint sl = id / 3, c = id % 3, n2 = N * N;
  float ls[kAccumMaxCoeffs], cs[kAccumMaxCoeffs];
  for (uint q = 0; q < n2; ++q) ls[q] = 0.0;
  for (uint k = sample_begin[sl]; k < sample_begin[sl + 1]; ++k) {
    const float l = lp[3 * k + c];
    for (uint q = 0; q < n2; ++q) ls[q] += l * basis[k * n2 + q];
  }
  const uint base = (sl * 3 + c) * n2;
  for (uint q = 0; q < n2; ++q) cs[q] = albedo[base + q];
  // Eq. 11: off-diagonal terms v (a_j b_k + a_k b_j), then diagonal v a_j b_j.
  float prod[kAccumMaxCoeffs];
  sh_plan_product(ls, cs, prod);
  for (uint i = 0; i < n2; ++i) outv[base + i] = prod[i];
}
