#version 450
// Upsampling weights of paper 000 section 4.2, eq. 11, one invocation per display pixel: the 2x2
// coarse block of bilinear weights w_b, times w_z = 1 / (eps + |z_p - z_i|) (as eps w_z =
// 1 / (1 + |z_p - z_i| / eps), eps = epsilon_rel z_p) and w_N = max(0, N_p . N_i)^power, renormalised;
// a miss where the unnormalised sum is below the threshold. Step by step the arithmetic of
// techniques/common/upsample.cpp (upsample_pixel), in float where the CPU uses double: the block
// (indices, taps dropped for w_b = 0) is exact in both for power-of-two scale ratios; the weights
// differ by float rounding (tests/vulkan/test_image_splat_parity.cpp bounds it).
#extension GL_GOOGLE_include_directive : require
#include "upsample_shared.h"

layout(local_size_x = kUpsampleGroupX, local_size_y = kUpsampleGroupY) in;

layout(std430, set = 0, binding = kUpBindFineDepth) readonly buffer FineDepth { float fdepth[]; };
layout(std430, set = 0, binding = kUpBindFineNormal) readonly buffer FineNormal { float fnormal[]; };
layout(std430, set = 0, binding = kUpBindCoarseDepth) readonly buffer CoarseDepth { float cdepth[]; };
layout(std430, set = 0, binding = kUpBindCoarseNormal) readonly buffer CoarseNormal { float cnormal[]; };
layout(std430, set = 0, binding = kUpBindIndex) writeonly buffer Index { ivec4 out_index[]; };
layout(std430, set = 0, binding = kUpBindWeight) writeonly buffer Weight { vec4 out_weight[]; };
layout(std430, set = 0, binding = kUpBindMiss) writeonly buffer Miss { uvec2 out_miss[]; };
layout(std430, set = 0, binding = kUpBindStatus) buffer Status { uint status[]; };
layout(push_constant) uniform Push {
  int fw, fh, fscale;   // display buffer
  int cw, ch, cscale;   // receiver buffer
  float epsilon_rel;
  int normal_power;
  float miss_threshold;
  uint mode;            // kUpsampleBilateral / kUpsampleBilinear
} pc;

bool is_hit(float z) { return !isinf(z); }
// UpsampleOptions' input rule: a positive finite depth, or +inf for background.
bool depth_ok(float z) { return (isinf(z) && z > 0.0) || (!isnan(z) && !isinf(z) && z > 0.0); }
bool normal_ok(vec3 n) { return !any(isnan(n)) && !any(isinf(n)); }

vec3 fine_normal(uint p) { return vec3(fnormal[3 * p], fnormal[3 * p + 1], fnormal[3 * p + 2]); }
vec3 coarse_normal(uint i) { return vec3(cnormal[3 * i], cnormal[3 * i + 1], cnormal[3 * i + 2]); }

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

int bn;
int bidx[4];
float bw[4];

void bilinear_block(int X, int Y) {
  const float ratio = float(pc.fscale) / float(pc.cscale);
  int x0, x1, y0, y1;
  float fx, fy;
  axis((float(X) + 0.5) * ratio - 0.5, pc.cw, x0, x1, fx);
  axis((float(Y) + 0.5) * ratio - 0.5, pc.ch, y0, y1, fy);
  const int xs[2] = int[2](x0, x1), ys[2] = int[2](y0, y1);
  const float wx[2] = float[2](1.0 - fx, fx), wy[2] = float[2](1.0 - fy, fy);
  bn = 0;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const float w = wx[i] * wy[j];
      if (w > 0.0) {
        bidx[bn] = ys[j] * pc.cw + xs[i];
        bw[bn] = w;
        ++bn;
      }
    }
}

// Keeps the taps with positive weight, normalised (upsample.cpp store_normalised).
bool store_normalised(float w[4], out ivec4 idx, out vec4 wt) {
  idx = ivec4(-1);
  wt = vec4(0.0);
  float sum = 0.0;
  for (int k = 0; k < bn; ++k) sum += w[k];
  if (!(sum > 0.0)) return false;
  int m = 0;
  for (int k = 0; k < bn; ++k)
    if (w[k] > 0.0) {
      idx[m] = bidx[k];
      wt[m] = w[k] / sum;
      ++m;
    }
  return true;
}

bool bilinear_valid(out ivec4 idx, out vec4 wt) {
  float w[4] = float[4](0.0, 0.0, 0.0, 0.0);
  for (int k = 0; k < bn; ++k) w[k] = is_hit(cdepth[bidx[k]]) ? bw[k] : 0.0;
  return store_normalised(w, idx, wt);
}

void main() {
  const int X = int(gl_GlobalInvocationID.x), Y = int(gl_GlobalInvocationID.y);
  // The coarse buffer is checked once, spread over the invocations of its own extent (the host
  // dispatches over the larger of both extents).
  if (X < pc.cw && Y < pc.ch) {
    const uint c = uint(Y) * uint(pc.cw) + uint(X);
    const float zc = cdepth[c];
    if (!depth_ok(zc) || (is_hit(zc) && !normal_ok(coarse_normal(c)))) atomicMin(status[kUpStatusBadCoarse], c + 1);
  }
  if (X >= pc.fw || Y >= pc.fh) return;
  const uint p = uint(Y) * uint(pc.fw) + uint(X);
  const float zp = fdepth[p];
  ivec4 idx = ivec4(-1);
  vec4 wt = vec4(0.0);
  uint miss = 0;
  float measure = 0.0;
  const vec3 np = fine_normal(p);
  if (!depth_ok(zp) || (is_hit(zp) && !normal_ok(np))) {
    atomicMin(status[kUpStatusBadFine], p + 1);
  } else if (is_hit(zp)) {  // background: nothing to shade, not a miss
    bilinear_block(X, Y);
    if (pc.mode == kUpsampleBilinear) {
      miss = bilinear_valid(idx, wt) ? 0u : 1u;
    } else {
      // Eq. 11 with eps w_z in (0, 1] (see upsample.cpp): the sum is the miss measure directly.
      const float eps = pc.epsilon_rel * zp;
      float w[4] = float[4](0.0, 0.0, 0.0, 0.0);
      for (int k = 0; k < bn; ++k) {
        const float zi = cdepth[bidx[k]];
        if (!is_hit(zi)) continue;
        const float dz = abs(zp - zi);
        const float wz = dz == 0.0 ? 1.0 : 1.0 / (1.0 + dz / eps);
        const float wn = ipow(max(0.0, dot(np, coarse_normal(uint(bidx[k])))), pc.normal_power);
        w[k] = bw[k] * wz * wn;
        measure += w[k];
      }
      if (measure > 0.0) {
        store_normalised(w, idx, wt);
        miss = measure < pc.miss_threshold ? 1u : 0u;
      } else {
        bilinear_valid(idx, wt);  // every eq. 11 weight vanished: bilinear over the valid taps, a miss
        miss = 1u;
      }
    }
  }
  out_index[p] = idx;
  out_weight[p] = wt;
  out_miss[p] = uvec2(miss, floatBitsToUint(measure));
}
