#version 450
// Diffuse shading of receivers (paper 004 eq. 9 and section 7; paper 000 eq. 10's first term), the
// CPU's shade_batch followed by add_lights_and_clamp (techniques/common/lights.cpp), per receiver:
//   E = max(0, (H(N) * g) . L + sum_lights L_H(theta, f) . g)  per colour channel,
// H(N)_lm = hcoef_l y_lm(N) (clamped cosine / pi with the rotation factor folded in), g the
// visibility windowed per coefficient, one SH product (shexp::ProductPlan) per receiver for the
// three channels. The visibility comes from the receiver (VIS = kShadeVisReceiver), from nowhere
// (kShadeVisNone: unshadowed, g = sqrt(4 pi) y_00), or is interpolated from a coarse field with
// per-pixel taps (kShadeVisGather: image_splat's eq. 11 upsampling of O_p, paper 000 section 4.2).
// Spherical lights (LIGHTS = 1): paper 004 section 7's single-lobe table L_H(theta, f), looked up and
// turned to the receiver's frame as shexp::light_lh_world does. Positions and normals come from
// six receiver planes (REC = kShadeRecPlanes) or, for a gather over display pixels, from the display
// G-buffer's planes where the Vulkan G-buffer pass left them (kShadeRecPixels).
#extension GL_GOOGLE_include_directive : require
// [[unroll]]: loops whose trip counts are the specialisation constant N (registers, not scratch).
#extension GL_EXT_control_flow_attributes : require
#include "softgi_shared.h"

layout(constant_id = 0) const uint N = SH_PLAN_FIXED_ORDER;  // shading order
#define SHEXP_BASIS_BINDING kShadeBindBasis
#define SHEXP_BASIS_ORDER N
#include "sh_basis.glsl"
#include "accum_math.glsl"
layout(constant_id = 1) const uint VIS = kShadeVisReceiver;
layout(constant_id = 2) const uint LIGHTS = 0;
layout(constant_id = 3) const uint REC = kShadeRecPlanes;
const bool VIS4 = (N * N) % 4u == 0u;
layout(local_size_x = kShadeGroup) in;

// Inputs through texel buffers: a SIMD device fetches texels for all lanes at once, where it reads a
// storage buffer lane by lane with a bounds check per component (llvmpipe).
layout(set = 0, binding = kShadeBindReceivers) uniform samplerBuffer rec;
layout(set = 0, binding = kShadeBindVis) uniform samplerBuffer vis;
// The constants, the same for every lane, in a uniform block: a texel fetch at one address costs a
// fetch per lane on a device that fetches lane by lane (llvmpipe), a uniform read one load.
layout(std140, set = 0, binding = kShadeBindConsts) uniform ShadeConsts { vec4 consts_v[kShadeConstFloats / 4u]; };
float shade_const(uint j) { return consts_v[j >> 2u][j & 3u]; }  // L (3 n^2), hcoef (n^2), gwin (n^2)
// With n^2 a multiple of 4 the visibility rows are read four floats to a texel (VIS4).
layout(set = 0, binding = kShadeBindVis4) uniform samplerBuffer vis4;
#include "sh_plan_products.glsl"
layout(std430, set = 0, binding = kShadeBindOut) writeonly buffer Out { vec4 outv[]; };
layout(set = 0, binding = kShadeBindTapPixel) uniform isamplerBuffer tap_pixel;
layout(set = 0, binding = kShadeBindTapIndex) uniform isamplerBuffer tap_index;
layout(set = 0, binding = kShadeBindTapWeight) uniform samplerBuffer tap_weight;
layout(set = 0, binding = kShadeBindCoarseRow) uniform isamplerBuffer coarse_row;
layout(set = 0, binding = kShadeBindLightTable) uniform samplerBuffer ltab;
layout(set = 0, binding = kShadeBindLights) uniform samplerBuffer lights;
// REC = kShadeRecPixels: receiver i is display pixel tap_pixel[i], read from the G-buffer's planes
// where the Vulkan G-buffer pass left them (the same floats the host planes hold).
layout(set = 0, binding = kShadeBindPixelPosition) uniform samplerBuffer pixel_position;
layout(set = 0, binding = kShadeBindPixelNormal) uniform samplerBuffer pixel_normal;
layout(std430, set = 0, binding = kShadeBindStatus) buffer Status { uint clamped; };
layout(push_constant) uniform Push {
  uint count;        // receivers in all (the planes of rec are this long)
  uint first;        // first receiver of this dispatch
  uint end;          // one past the last
  uint flags;        // kShadeFlag*
  uint light_count;  // spherical lights (LIGHTS = 1)
  uint rows_theta;   // light table rows in theta over [0, pi/2] ...
  uint rows_f;       // ... and in f over [0, pi]
  float theta_floor; // the smallest theta the light table's solid-angle normalisation uses (lights.cpp)
} pc;

const float kSqrt4Pi = 3.5449077018110318;

// LightLobeTable::lookup's coordinate: clamped to the table, the last cell interpolating to its end.
void table_coord(float x, float range, uint rows, out uint k0, out float w) {
  float u = x / range * float(rows - 1);
  if (!(u > 0.0)) u = 0.0;
  if (u > float(rows - 1)) u = float(rows - 1);
  k0 = min(uint(u), rows - 2);
  w = u - float(k0);
}

// Paper 004 section 7: L_H of a spherical light (centre c, radius R) at p with normal n, dotted with g
// (shexp::light_lh_world + LightLobeTable::lookup, then the dot product of the CPU's light loop).
// Returns false where the CPU skips the light (degenerate distance or radius).
bool light_dot(vec3 p, vec3 n, vec3 c, float R, float g[kAccumMaxCoeffs], out float dsum) {
  dsum = 0.0;
  const vec3 d = c - p;
  const float dist = length(d);
  if (!(dist > 0.0) || !(R > 0.0)) return false;
  const float theta = dist > R ? accum_asin01(R / dist) : kAccumHalfPi;
  const vec3 dir = d / dist;
  const float cf = clamp(dot(dir, n), -1.0, 1.0);
  const float f = accum_acos(cf);
  uint i0, j0;
  float wi, wj;
  table_coord(theta, kAccumHalfPi, pc.rows_theta, i0, wi);
  table_coord(f, kAccumPi, pc.rows_f, j0, wj);
  const float w[4] = float[4]((1.0 - wi) * (1.0 - wj), (1.0 - wi) * wj, wi * (1.0 - wj), wi * wj);
  const uint cells[4] = uint[4](i0 * pc.rows_f + j0, i0 * pc.rows_f + j0 + 1, (i0 + 1) * pc.rows_f + j0, (i0 + 1) * pc.rows_f + j0 + 1);
  const uint kbase = pc.rows_theta * pc.rows_f;  // k follows the psi plane
  float psi = 0.0;
  float k[kAccumMaxOrder];
  [[unroll]] for (uint l = 0; l < N; ++l) k[l] = 0.0;
  for (uint q = 0; q < 4; ++q) {
    psi += w[q] * texelFetch(ltab, int(cells[q])).x;
    [[unroll]] for (uint l = 0; l < N; ++l) k[l] += w[q] * texelFetch(ltab, int(kbase + cells[q] * N + l)).x;
  }
  // k is stored per unit solid angle of the light: multiplied back by 4 pi sin^2(theta / 2).
  const float sh = accum_sincos_quarter(0.5 * max(theta, pc.theta_floor)).x;
  const float omega = 4.0 * kAccumPi * sh * sh;
  // Canonical frame: N = z, light in the xz plane on the +x side; the lobe axis at psi from z.
  vec3 tang = dir - cf * n;
  const float tl = length(tang);
  if (tl > 1e-6) {
    tang /= tl;
  } else {  // light on the normal: the lobe is on the normal too (psi = 0 or pi), any tangent will do
    tang = abs(n.x) < 0.9 ? normalize(cross(n, vec3(1, 0, 0))) : normalize(cross(n, vec3(0, 1, 0)));
  }
  const vec2 sc = accum_sincos_half(psi);
  const vec3 axis = sc.y * n + sc.x * tang;
  float Y[kAccumMaxCoeffs];
  sh_basis_eval(axis, Y);
  float kl[kAccumMaxOrder];
  [[unroll]] for (uint l = 0; l < N; ++l) kl[l] = k[l] * omega;
  [[unroll]] for (uint q = 0; q < N * N; ++q) dsum += (kl[kShBand[q]] * Y[q]) * g[q];
  return true;
}

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const uint n2 = N * N;
  const int n = int(pc.count), ii = int(i);
  vec3 p, s;
  if (REC == kShadeRecPixels) {
    const int px = texelFetch(tap_pixel, ii).x;
    p = texelFetch(pixel_position, px).xyz;
    s = texelFetch(pixel_normal, px).xyz;
  } else {
    p = vec3(texelFetch(rec, ii).x, texelFetch(rec, n + ii).x, texelFetch(rec, 2 * n + ii).x);
    s = vec3(texelFetch(rec, 3 * n + ii).x, texelFetch(rec, 4 * n + ii).x, texelFetch(rec, 5 * n + ii).x);
  }
  if ((pc.flags & kShadeFlagZeroNormalEmpty) != 0u && s == vec3(0.0)) {  // no surface (DirectShader::shade)
    outv[i] = vec4(0.0);
    return;
  }
  float H[kAccumMaxCoeffs], g[kAccumMaxCoeffs];
  sh_basis_eval(s, H);
  [[unroll]] for (uint k = 0; k < n2; ++k) g[k] = 0.0;
  bool unshadowed = VIS == kShadeVisNone;
  if (VIS == kShadeVisReceiver) {
    if (VIS4) {
      [[unroll]] for (uint q = 0; q < n2 / 4u; ++q) {
        const vec4 v = texelFetch(vis4, int(i * (n2 / 4u) + q));
        g[4u * q] = v.x;
        g[4u * q + 1u] = v.y;
        g[4u * q + 2u] = v.z;
        g[4u * q + 3u] = v.w;
      }
    } else {
      [[unroll]] for (uint k = 0; k < n2; ++k) g[k] = texelFetch(vis, int(i * n2 + k)).x;
    }
  } else if (VIS == kShadeVisGather) {
    // Eq. 11 (paper 000): sum over the pixel's taps, in the CPU's order; no tap at all: unshadowed.
    const int px = texelFetch(tap_pixel, ii).x;
    const ivec4 idx = texelFetch(tap_index, px);
    const vec4 wt = texelFetch(tap_weight, px);
    unshadowed = idx.x < 0;
    for (int t = 0; t < 4 && idx[t] >= 0; ++t) {
      // The field's row of the tap's coarse sample: the sample itself, or (a field in another
      // order, as O_p in receiver order) its entry of coarse_row.
      const uint row = (pc.flags & kShadeFlagCoarseRow) != 0u ? uint(texelFetch(coarse_row, idx[t]).x) : uint(idx[t]);
      if (VIS4) {
        const uint base4 = row * (n2 / 4u);
        [[unroll]] for (uint q = 0; q < n2 / 4u; ++q) {
          const vec4 v = texelFetch(vis4, int(base4 + q));
          g[4u * q] += wt[t] * v.x;
          g[4u * q + 1u] += wt[t] * v.y;
          g[4u * q + 2u] += wt[t] * v.z;
          g[4u * q + 3u] += wt[t] * v.w;
        }
      } else {
        const uint base = row * n2;
        [[unroll]] for (uint k = 0; k < n2; ++k) g[k] += wt[t] * texelFetch(vis, int(base + k)).x;
      }
    }
  }
  if (unshadowed) {
    [[unroll]] for (uint k = 0; k < n2; ++k) g[k] = k == 0 ? kSqrt4Pi : 0.0;
  }
  [[unroll]] for (uint k = 0; k < n2; ++k) {
    H[k] *= shade_const(3u * n2 + k);  // hcoef
    g[k] *= shade_const(4u * n2 + k);  // gwin
  }
  // (H * g)_k (eq. 3), then dotted with the light.
  float hg[kAccumMaxCoeffs];
  sh_plan_product(H, g, hg);
  vec3 e = vec3(0.0);
  [[unroll]] for (uint k = 0; k < n2; ++k)
    e += hg[k] * vec3(shade_const(k), shade_const(n2 + k), shade_const(2u * n2 + k));
  if (LIGHTS != 0) {
    for (uint li = 0; li < pc.light_count; ++li) {
      const vec4 cr = texelFetch(lights, int(2 * li));
      float dsum;
      if (light_dot(p, s, cr.xyz, cr.w, g, dsum)) e += dsum * texelFetch(lights, int(2 * li + 1)).xyz;
    }
  }
  // Truncated SH can ring below zero in deep shadow; outgoing radiance cannot.
  if (e.x < 0.0 || e.y < 0.0 || e.z < 0.0) atomicAdd(clamped, 1u);
  outv[i] = vec4(max(e, vec3(0.0)), 0.0);
}
