#version 450
// Upsampling weights of paper 000 section 4.2, eq. 11, one invocation per display pixel that sees a
// surface (the host lists them, fills the background's outputs: no taps, not a miss, and checks the
// inputs, upsample_vulkan.cpp; a SIMD device runs a shader's every branch for all lanes, so an
// invocation per background pixel would cost as much as one per surface pixel). The 2x2
// coarse block of bilinear weights w_b, times w_z = 1 / (eps + |z_p - z_i|) (as eps w_z =
// 1 / (1 + |z_p - z_i| / eps), eps = epsilon_rel z_p) and w_N = max(0, N_p . N_i)^power, renormalised;
// a miss where the unnormalised sum is below the threshold. Step by step the arithmetic of
// techniques/common/upsample.cpp (upsample_pixel), in float where the CPU uses double: the block
// (indices, taps dropped for w_b = 0) is exact in both for power-of-two scale ratios; the weights
// differ by float rounding (tests/vulkan/test_image_splat_parity.cpp bounds it).
#extension GL_GOOGLE_include_directive : require
#include "upsample_shared.h"

layout(local_size_x = kUpWeightsGroup) in;

// Through texel buffers: a SIMD device fetches and stores texels for all lanes at once, where it
// reads and writes a storage buffer lane by lane with a bounds check per component (llvmpipe).
// A sample's normal and depth in one RGBA32F texel: one fetch per sample (llvmpipe runs each fetch
// as a gather of its own; with depth and the three normal components in four single-float texels a
// pixel took twenty).
layout(set = 0, binding = kUpBindSurface) uniform usamplerBuffer surface;
layout(set = 0, binding = kUpBindFine) uniform samplerBuffer fine_nz;
layout(set = 0, binding = kUpBindCoarse) uniform samplerBuffer coarse_nz;
layout(set = 0, binding = kUpBindIndex, rgba32i) uniform writeonly iimageBuffer out_index;
layout(set = 0, binding = kUpBindWeight, rgba32f) uniform writeonly imageBuffer out_weight;
layout(set = 0, binding = kUpBindMiss, rg32ui) uniform writeonly uimageBuffer out_miss;
layout(push_constant) uniform Push {
  uint first, end;      // surface pixels of this dispatch
  int fw, fh, fscale;   // display buffer
  int cw, ch, cscale;   // receiver buffer
  float epsilon_rel;
  int normal_power;
  float miss_threshold;
} pc;
// kUpsampleBilateral or kUpsampleBilinear, a specialisation constant: a SIMD device runs both sides
// of a branch (llvmpipe does even when every lane takes the same side), which a push constant would
// leave in the code.
layout(constant_id = 0) const uint MODE = kUpsampleBilateral;

bool is_hit(float z) { return !isinf(z); }

vec4 fine_sample(uint p) { return texelFetch(fine_nz, int(p)); }
vec4 coarse_sample(int i) { return texelFetch(coarse_nz, i); }

// b^e by squaring (upsample.cpp ipow); 0^0 = 1.
float ipow(float b, int e) {
  float r = 1.0;
  while (e > 0) {
    if ((e & 1) != 0) r *= b;
    b *= b;
    e >>= 1;
  }
  return r;
}

// One axis of the bilinear footprint, clamp-to-edge (upsample.cpp axis()).
void axis(float u, int n, out int i0, out int i1, out float f) {
  u = clamp(u, 0.0, float(n - 1));
  i0 = min(int(floor(u)), max(n - 2, 0));
  i1 = min(i0 + 1, n - 1);
  f = u - float(i0);
}

// The 2x2 block of bilinear taps in upsample.cpp's order, (x0, y0), (x1, y0), (x0, y1), (x1, y1),
// as vectors: a tap of weight 0 (upsample.cpp leaves it out) keeps weight 0 below and adds exact
// zeros to every sum, so the sums are those of the taps kept, in their order. Vectors with
// constant components and no arrays: a SIMD device keeps per-invocation arrays in memory.
void bilinear_block(int X, int Y, out ivec4 bidx, out vec4 bw) {
  const float ratio = float(pc.fscale) / float(pc.cscale);
  int x0, x1, y0, y1;
  float fx, fy;
  axis((float(X) + 0.5) * ratio - 0.5, pc.cw, x0, x1, fx);
  axis((float(Y) + 0.5) * ratio - 0.5, pc.ch, y0, y1, fy);
  bidx = ivec4(y0 * pc.cw + x0, y0 * pc.cw + x1, y1 * pc.cw + x0, y1 * pc.cw + x1);
  bw = vec4((1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy);
}

// Appends tap (i, w) at place m of (idx, wt) when w > 0.
void keep(int i, float w, float sum, inout int m, inout ivec4 idx, inout vec4 wt) {
  if (!(w > 0.0)) return;
  const float v = w / sum;
  idx = ivec4(m == 0 ? i : idx.x, m == 1 ? i : idx.y, m == 2 ? i : idx.z, m == 3 ? i : idx.w);
  wt = vec4(m == 0 ? v : wt.x, m == 1 ? v : wt.y, m == 2 ? v : wt.z, m == 3 ? v : wt.w);
  ++m;
}

// Keeps the taps with positive weight, normalised (upsample.cpp store_normalised).
bool store_normalised(ivec4 bidx, vec4 w, out ivec4 idx, out vec4 wt) {
  idx = ivec4(-1);
  wt = vec4(0.0);
  const float sum = ((w.x + w.y) + w.z) + w.w;
  if (!(sum > 0.0)) return false;
  int m = 0;
  keep(bidx.x, w.x, sum, m, idx, wt);
  keep(bidx.y, w.y, sum, m, idx, wt);
  keep(bidx.z, w.z, sum, m, idx, wt);
  keep(bidx.w, w.w, sum, m, idx, wt);
  return true;
}

// The bilinear taps over the block's valid (hit) samples, whose depths are `z`.
bool bilinear_valid(ivec4 bidx, vec4 bw, vec4 z, out ivec4 idx, out vec4 wt) {
  const vec4 w = vec4(is_hit(z.x) ? bw.x : 0.0, is_hit(z.y) ? bw.y : 0.0, is_hit(z.z) ? bw.z : 0.0, is_hit(z.w) ? bw.w : 0.0);
  return store_normalised(bidx, w, idx, wt);
}

// Eq. 11's weight of one tap, coarse sample s: w_b w_z w_N, 0 for a background tap or one of weight 0.
float bilateral(vec4 s, float wb, float zp, float eps, vec3 np) {
  if (!(wb > 0.0)) return 0.0;
  const float zi = s.w;
  if (!is_hit(zi)) return 0.0;
  const float dz = abs(zp - zi);
  const float wz = dz == 0.0 ? 1.0 : 1.0 / (1.0 + dz / eps);
  const float wn = ipow(max(0.0, dot(np, s.xyz)), pc.normal_power);
  return wb * wz * wn;
}

void main() {
  const uint j = pc.first + gl_GlobalInvocationID.x;
  if (j >= pc.end) return;
  const uint p = texelFetch(surface, int(j)).x;
  const int X = int(p % uint(pc.fw)), Y = int(p / uint(pc.fw));
  const vec4 sp = fine_sample(p);
  const float zp = sp.w;
  const vec3 np = sp.xyz;
  ivec4 idx = ivec4(-1);
  vec4 wt = vec4(0.0);
  uint miss = 0;
  float measure = 0.0;
  ivec4 bidx;
  vec4 bw;
  bilinear_block(X, Y, bidx, bw);
  // The block's four samples fetched once (the clamped indices are always inside the buffer; a tap
  // of weight 0 ignores its sample).
  const vec4 s0 = coarse_sample(bidx.x), s1 = coarse_sample(bidx.y), s2 = coarse_sample(bidx.z), s3 = coarse_sample(bidx.w);
  const vec4 z = vec4(s0.w, s1.w, s2.w, s3.w);
  if (MODE == kUpsampleBilinear) {
    miss = bilinear_valid(bidx, bw, z, idx, wt) ? 0u : 1u;
  } else {
    // Eq. 11 with eps w_z in (0, 1] (see upsample.cpp): the sum is the miss measure directly.
    const float eps = pc.epsilon_rel * zp;
    const vec4 w = vec4(bilateral(s0, bw.x, zp, eps, np), bilateral(s1, bw.y, zp, eps, np), bilateral(s2, bw.z, zp, eps, np),
                        bilateral(s3, bw.w, zp, eps, np));
    measure = ((w.x + w.y) + w.z) + w.w;
    if (measure > 0.0) {
      store_normalised(bidx, w, idx, wt);
      miss = measure < pc.miss_threshold ? 1u : 0u;
    } else {
      bilinear_valid(bidx, bw, z, idx, wt);  // every eq. 11 weight vanished: bilinear over the valid taps, a miss
      miss = 1u;
    }
  }
  imageStore(out_index, int(p), idx);
  imageStore(out_weight, int(p), wt);
  imageStore(out_miss, int(p), uvec4(miss, floatBitsToUint(measure), 0u, 0u));
}
