// Shared by point_voxels' shaders (paper 002): the grid, the proxy and pixel records, and the
// functions of techniques/point_voxels/pv_core.cpp they need, written to evaluate the same float
// operations in the same order (eq. 1's hash, the ray-disc test, the 3D DDA of march_ray, the
// cosine-distributed ray set). Expects pv_shared.h included.
#ifndef SOFTGI_PV_COMMON_GLSL
#define SOFTGI_PV_COMMON_GLSL

layout(std430, set = 0, binding = kPvBindGrid) readonly buffer Grid {
  vec4 g_lo_r;     // lo, disc radius
  vec4 g_cell_a;   // cell size, patch area (the VPL's emitting area)
  vec4 g_inv_cell; // 1 / cell size
  ivec4 g_dims;    // cells per axis, cells
  uvec4 g_counts;  // proxies
};

struct Proxy {
  vec4 position;
  vec4 normal;
  vec4 albedo;
  uvec4 meta;  // environment ray seed, sampling index, voxel key, 0
};
// A pixel of the marching G-buffer: position (w: 1 hit, 0 background), normal (w: eye-space depth),
// the seed of its rays (x).
struct MarchPixel {
  vec4 pos_hit;
  vec4 normal_depth;
  uvec4 seed;
};
struct MarchItem {
  uvec4 state;     // phase, DDA steps before the current cell, next disc of it, voxel hit (int bits)
  vec4 radiance;   // the sky's radiance along an escaped ray
};

const float kPvPi = 3.14159265358979324;

// Eq. 1: H(v) = v.z Dx Dy + v.y Dx + v.x.
uint pv_hash(ivec3 v, ivec3 dims) { return uint(v.z) * uint(dims.x) * uint(dims.y) + uint(v.y) * uint(dims.x) + uint(v.x); }
uint pv_hash(ivec3 v) { return pv_hash(v, g_dims.xyz); }

// VoxelGrid::cell_of: by the reciprocal of the cell size, so that both backends round alike.
ivec3 pv_cell_of(vec3 p) { return clamp(ivec3(floor((p - g_lo_r.xyz) * g_inv_cell.xyz)), ivec3(0), g_dims.xyz - 1); }

// ray_disc: t of the hit of o + t d with the disc (c, n, r), negative for none.
float pv_ray_disc(vec3 o, vec3 d, vec3 c, vec3 n, float r) {
  const float dn = dot(d, n);
  if (abs(dn) < 1e-8) return -1.0;
  const float t = dot(c - o, n) / dn;
  if (!(t >= 0.0)) return -1.0;
  const vec3 q = o + t * d - c;
  return dot(q, q) <= r * r ? t : -1.0;
}

// (sin, cos) of phi in [-pi/4, 3pi/4] by Taylor polynomials on [-pi/4, pi/4] (truncation below 1e-9,
// under a float ulp): Vulkan bounds the built-in sin and cos only to 2^-11 absolute.
vec2 pv_sincos(float phi) {
  const bool near = phi <= 0.25 * kPvPi;
  const float a = near ? phi : 0.5 * kPvPi - phi;
  const float a2 = a * a;
  const float s = a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362880.0 + a2 * (-1.0 / 39916800.0))))));
  const float c = 1.0 + a2 * (-0.5 + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40320.0 + a2 * (-1.0 / 3628800.0 + a2 * (1.0 / 479001600.0))))));
  return near ? vec2(s, c) : vec2(c, s);
}

// cosine_direction: Shirley-Chiu's concentric map of (u, v), lifted to the hemisphere about n.
vec3 pv_cosine_direction(vec3 n, float u, float v) {
  const float a = 2.0 * u - 1.0, b = 2.0 * v - 1.0;
  float r, phi;
  if (a == 0.0 && b == 0.0) {
    r = 0.0;
    phi = 0.0;
  } else if (abs(a) > abs(b)) {
    r = a;
    phi = (kPvPi / 4.0) * (b / a);
  } else {
    r = b;
    phi = (kPvPi / 2.0) - (kPvPi / 4.0) * (a / b);
  }
  const vec2 sc = pv_sincos(phi);
  const float x = r * sc.y, y = r * sc.x, z = sqrt(max(0.0, 1.0 - x * x - y * y));
  const vec3 t = abs(n.x) > 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
  const vec3 tu = normalize(cross(t, n)), tv = cross(n, tu);
  return normalize(x * tu + y * tv + z * n);
}

// ray_sample: ray k of n, stratified in u, base-2 radical inverse in v, rotated by the seed.
vec2 pv_ray_sample(uint k, uint n, uint seed) {
  const float u = (float(k) + 0.5) / float(n) + float(seed & 0xffffu) * (1.0 / 65536.0);
  const float v = float(bitfieldReverse(k + 1u)) * 2.3283064365386963e-10 + float(seed >> 16) * (1.0 / 65536.0);
  return vec2(u - floor(u), v - floor(v));
}

// The real SH basis of the project (sh::eval_basis) for l <= 1, as pv_core.cpp's basis2.
vec4 pv_basis2(vec3 w) {
  const float y0 = 0.28209479177387814, y1 = 0.4886025119029199;
  return vec4(y0, y1 * w.y, y1 * w.z, y1 * w.x);
}

#endif
