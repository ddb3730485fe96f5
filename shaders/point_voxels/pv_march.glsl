// The marching functions of point_voxels' shaders (paper 002 section 3.1): march_ray with a loop
// budget, and the sky's radiance along escaped rays. Expects pv_common.glsl included and `prox`
// (sorted proxies), `cell_start` (cell ranges) and, with PV_SKY defined, `sky_sh` declared.
#ifndef SOFTGI_PV_MARCH_GLSL
#define SOFTGI_PV_MARCH_GLSL

#ifdef PV_SKY
// Lights::sky_radiance: the order-3 SH of the sky (`sky_sh`, 9 RGB coefficients) at w, clamped at
// 0. The basis of sh::eval_basis written out for l <= 2: y_lm = K_lm P_lm(z) {cos, sin}(m phi) with
// (x + i y)^m for the azimuthal factors, index l^2 + l + m.
vec3 pv_sky_radiance(vec3 w) {
  const float k0 = 0.28209479177387814, k1 = 0.4886025119029199, k2m1 = 1.0925484305920792, k20 = 0.31539156525252005,
              k22 = 0.5462742152960396;
  vec3 l = sky_sh[0].xyz * k0;
  l += sky_sh[1].xyz * (k1 * w.y) + sky_sh[2].xyz * (k1 * w.z) + sky_sh[3].xyz * (k1 * w.x);
  l += sky_sh[4].xyz * (k22 * (2.0 * w.x * w.y)) + sky_sh[5].xyz * (k2m1 * w.z * w.y) + sky_sh[6].xyz * (k20 * (3.0 * w.z * w.z - 1.0)) +
       sky_sh[7].xyz * (k2m1 * w.z * w.x) + sky_sh[8].xyz * (k22 * (w.x * w.x - w.y * w.y));
  return max(l, vec3(0.0));
}
#endif

// march_ray with a loop budget: the first voxel along o + t d (t in [t_min, t_max]) whose discs the
// ray hits, -1 when it leaves the grid, -2 when `budget` loop iterations ran out first; then `steps`
// (cells stepped) and `disc` (next disc of the current cell) say where to resume, and the next call
// with them replays the DDA to that cell without testing discs. A driver that limits loop iterations
// per SIMD batch of invocations (llvmpipe) counts every iteration the batch runs, of the outer loop
// (a DDA step) and of the inner one (a disc test), however many of its lanes take part; so every
// lane counts every iteration in `spent`, which the subgroup keeps equal in all its lanes (the inner
// loop runs for the whole subgroup), and the batch stops at the budget. Expects `discs` (the sorted proxies as RGBA32F
// texels, 4 per proxy) and `cell_start` (cell ranges, R32UI texels) declared: a SIMD device fetches
// texels for all lanes at once, where it reads a storage buffer lane by lane.
int pv_march(vec3 o, vec3 d, float t_min, float t_max, inout uint steps, inout uint disc, uint budget) {
  if (g_counts.x == 0u) return -1;
  // The grid once in registers: the loops below would read it from its storage buffer every step.
  const ivec3 dims = g_dims.xyz;
  const vec3 lo = g_lo_r.xyz, hi = lo + g_cell_a.xyz * vec3(dims);
  float t0 = t_min, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    if (abs(d[a]) < 1e-12) {
      if (o[a] < lo[a] || o[a] > hi[a]) return -1;
      continue;
    }
    float ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) {
      const float x = ta;
      ta = tb;
      tb = x;
    }
    t0 = max(t0, ta);
    t1 = min(t1, tb);
  }
  if (!(t0 <= t1)) return -1;
  ivec3 v = pv_cell_of(o + d * t0);
  ivec3 stp = ivec3(0);
  vec3 t_next = vec3(0.0), t_delta = vec3(0.0);
  for (int a = 0; a < 3; ++a) {
    if (abs(d[a]) < 1e-12) {
      stp[a] = 0;
      t_next[a] = uintBitsToFloat(0x7f800000u);
      t_delta[a] = uintBitsToFloat(0x7f800000u);
      continue;
    }
    stp[a] = d[a] > 0.0 ? 1 : -1;
    const float boundary = lo[a] + float(v[a] + (stp[a] > 0 ? 1 : 0)) * g_cell_a[a];
    t_next[a] = (boundary - o[a]) / d[a];
    t_delta[a] = g_cell_a[a] / abs(d[a]);
  }
  const float r = g_lo_r.w;
  const uint target = steps;  // cells to replay before testing discs again
  uint taken = 0u, spent = 0u, k = 0u, cell_b = 0u, i = 0u, e = 0u;
  if (target == 0u) {
    k = pv_hash(v, dims);
    cell_b = texelFetch(cell_start, int(k)).x;
    i = cell_b + disc;
    e = texelFetch(cell_start, int(k + 1u)).x;
  }
  for (;;) {
    if (++spent > budget) {
      if (taken < target) return -2;  // still replaying: the saved place stands
      steps = taken;
      disc = i - cell_b;
      return -2;
    }
    if (subgroupAny(i < e)) {
      // The cells' discs in a loop of their own: a SIMD device runs every branch of this loop's
      // body for every iteration (masked), so each disc test would pay for a DDA step too. The
      // subgroup runs it until none of its lanes has a disc left, and every lane counts every
      // iteration: `spent` stays the same in all lanes and equal to the iterations the SIMD batch
      // ran, which is what the driver limits (a lane that counted only its own discs would let the
      // batch run past the limit while its lanes wait on the longest).
      while (spent < budget && subgroupAny(i < e)) {
        ++spent;
        if (i < e) {
          const float t = pv_ray_disc(o, d, texelFetch(discs, int(4u * i)).xyz, texelFetch(discs, int(4u * i + 1u)).xyz, r);
          if (t >= t_min && t <= t_max) return int(k);
          ++i;
        }
      }
      continue;  // out of budget (spent == budget): the next iteration saves the place
    }
    int a = 0;
    if (t_next[1] < t_next[a]) a = 1;
    if (t_next[2] < t_next[a]) a = 2;
    if (t_next[a] > t1) return -1;
    v[a] += stp[a];
    if (v[a] < 0 || v[a] >= dims[a]) return -1;
    t_next[a] += t_delta[a];
    ++taken;
    if (taken >= target) {
      k = pv_hash(v, dims);
      cell_b = texelFetch(cell_start, int(k)).x;
      i = cell_b + (taken == target ? disc : 0u);
      e = texelFetch(cell_start, int(k + 1u)).x;
    }
  }
  return -1;
}

#endif
