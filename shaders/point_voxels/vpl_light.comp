#version 450
// The proxies as VPLs (paper 002 Figure 2a): each sorted proxy's irradiance from the local lights
// through their cube depth maps, the sun through its directional map and the sky through its marched
// environment rays, its outgoing radiance albedo E / pi (eqs. 2-3 are summed per voxel by
// vpl_finish). One invocation per sorted proxy of the batch. As pass_light_vpls (point_voxels.cpp).
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvLitBindProxies) readonly buffer Proxies { Proxy prox[]; };
layout(std430, set = 0, binding = kPvLitBindItems) readonly buffer Items { MarchItem items[]; };
layout(std430, set = 0, binding = kPvLitBindLights) readonly buffer Lights { vec4 lights[]; };
layout(std430, set = 0, binding = kPvLitBindCube) readonly buffer Cube { float cube[]; };
layout(std430, set = 0, binding = kPvLitBindSun) readonly buffer Sun { float sun[]; };
layout(std430, set = 0, binding = kPvLitBindRadiance) writeonly buffer Radiance { vec4 radiance[]; };
layout(push_constant) uniform Push {
  uint first, end;       // sorted proxies of this dispatch
  uint first_item;       // the batch's first proxy: items hold (proxy - first_item) * env_rays + k
  uint local_lights;
  uint cube_size;
  uint env_rays;         // 0: no environment rays
  float env_scale;       // pi / env_rays
  uint has_sun;
  vec4 sun_irradiance;   // rgb
} pc;

// CubeDepthMap::visibility: 3 x 3 percentage-closer filtering about the texel of p offset by two
// texels' footprint along its normal.
float cube_visibility(uint l, vec3 p, vec3 pn) {
  const vec3 center = lights[2u * l].xyz;
  vec3 d = p - center;
  const float dist = length(d);
  if (!(dist > 0.0)) return 1.0;
  const float size = float(pc.cube_size);
  d += pn * (2.0 * 2.0 * dist / size);
  int a = 0;
  if (abs(d.y) > abs(d[a])) a = 1;
  if (abs(d.z) > abs(d[a])) a = 2;
  const int face = 2 * a + (d[a] < 0.0 ? 1 : 0), ua = (a + 1) % 3, va = (a + 2) % 3;
  const float z = abs(d[a]);
  const float fx = (d[ua] / z + 1.0) * 0.5 * size, fy = (d[va] / z + 1.0) * 0.5 * size;
  const int n = int(pc.cube_size);
  const int cx = clamp(int(fx), 0, n - 1), cy = clamp(int(fy), 0, n - 1);
  const float bias = z * (1e-3 + 2.0 / size);
  const uint base = (l * 6u + uint(face)) * pc.cube_size * pc.cube_size;
  int lit = 0, count = 0;
  for (int j = cy - 1; j <= cy + 1; ++j)
    for (int i = cx - 1; i <= cx + 1; ++i) {
      if (i < 0 || j < 0 || i >= n || j >= n) continue;
      ++count;
      lit += z <= cube[base + uint(j) * pc.cube_size + uint(i)] + bias ? 1 : 0;
    }
  return count > 0 ? float(lit) / float(count) : 1.0;
}

// OrthoDepthMap::visibility. Header: dir, u, v, lo, extent, size.
float sun_visibility(vec3 p, vec3 pn) {
  const vec3 dir = vec3(sun[0], sun[1], sun[2]), u = vec3(sun[3], sun[4], sun[5]), v = vec3(sun[6], sun[7], sun[8]);
  const vec2 lo = vec2(sun[9], sun[10]), extent = vec2(sun[11], sun[12]);
  const int size = int(sun[13]);
  const float texel = max(extent.x, extent.y) / float(size);
  const vec3 q = p + pn * (2.0 * texel);
  const float fx = (dot(q, u) - lo.x) / extent.x * float(size), fy = (dot(q, v) - lo.y) / extent.y * float(size);
  const int cx = int(floor(fx)), cy = int(floor(fy));
  const float z = -dot(q, dir), bias = 2.0 * texel;
  int lit = 0, count = 0;
  for (int j = cy - 1; j <= cy + 1; ++j)
    for (int i = cx - 1; i <= cx + 1; ++i) {
      ++count;
      if (i < 0 || j < 0 || i >= size || j >= size) {
        ++lit;
        continue;
      }
      lit += z <= sun[kPvSunHeader + uint(j) * uint(size) + uint(i)] + bias ? 1 : 0;
    }
  return float(lit) / float(count);
}

// local_irradiance: L pi R^2 / d^2 times the cosine.
vec3 local_irradiance(uint l, vec3 p, vec3 n) {
  const vec4 cr = lights[2u * l];
  const vec3 w = cr.xyz - p;
  const float d2 = max(dot(w, w), 1.0001 * cr.w * cr.w);
  const vec3 dir = w / sqrt(dot(w, w) > 0.0 ? dot(w, w) : 1.0);
  const float c = dot(n, dir);
  if (c <= 0.0) return vec3(0.0);
  return lights[2u * l + 1u].xyz * (kPvPi * cr.w * cr.w / d2 * c);
}

void main() {
  const uint i = pc.first + gl_GlobalInvocationID.x;
  if (i >= pc.end) return;
  const vec3 p = prox[i].position.xyz, nn = prox[i].normal.xyz;
  vec3 e = vec3(0.0);
  for (uint l = 0u; l < pc.local_lights; ++l) {
    const vec3 el = local_irradiance(l, p, nn);
    if (el != vec3(0.0)) e += el * cube_visibility(l, p, nn);
  }
  if (pc.has_sun != 0u) {
    const float c = dot(nn, vec3(sun[0], sun[1], sun[2]));
    if (c > 0.0) e += pc.sun_irradiance.xyz * (c * sun_visibility(p, nn));
  }
  if (pc.env_rays > 0u) {
    vec3 sky = vec3(0.0);
    const uint base = (i - pc.first_item) * pc.env_rays;
    for (uint k = 0u; k < pc.env_rays; ++k) sky += items[base + k].radiance.xyz;
    e += sky * pc.env_scale;
  }
  const vec3 rad = prox[i].albedo.xyz * e / kPvPi;
  radiance[i] = vec4(rad, 0.0);
}
