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

// march_ray's 3D DDA over the grid (paper 002 section 3.1): the cell o + t d enters at t_min
// (clipped to the grid), and the crossings of the cell boundaries ahead per axis.
struct PvDda {
  ivec3 v, stp;
  vec3 t_next, t_delta;
  float t1;  // where the ray leaves the grid or t_max
};

// false when the ray misses the grid within [t_min, t_max].
bool pv_dda_begin(vec3 o, vec3 d, float t_min, float t_max, out PvDda q) {
  // The grid once in registers: the loops that follow would read it from its storage buffer every step.
  const ivec3 dims = g_dims.xyz;
  const vec3 lo = g_lo_r.xyz, hi = lo + g_cell_a.xyz * vec3(dims);
  float t0 = t_min;
  q.t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    if (abs(d[a]) < 1e-12) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    float ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) {
      const float x = ta;
      ta = tb;
      tb = x;
    }
    t0 = max(t0, ta);
    q.t1 = min(q.t1, tb);
  }
  if (!(t0 <= q.t1)) return false;
  q.v = pv_cell_of(o + d * t0);
  q.stp = ivec3(0);
  q.t_next = vec3(0.0);
  q.t_delta = vec3(0.0);
  for (int a = 0; a < 3; ++a) {
    if (abs(d[a]) < 1e-12) {
      q.stp[a] = 0;
      q.t_next[a] = uintBitsToFloat(0x7f800000u);
      q.t_delta[a] = uintBitsToFloat(0x7f800000u);
      continue;
    }
    q.stp[a] = d[a] > 0.0 ? 1 : -1;
    const float boundary = lo[a] + float(q.v[a] + (q.stp[a] > 0 ? 1 : 0)) * g_cell_a[a];
    q.t_next[a] = (boundary - o[a]) / d[a];
    q.t_delta[a] = g_cell_a[a] / abs(d[a]);
  }
  return true;
}

// One step to the next cell; false when the ray leaves the grid or passes t_max.
bool pv_dda_step(inout PvDda q, ivec3 dims) {
  int a = 0;
  if (q.t_next[1] < q.t_next[a]) a = 1;
  if (q.t_next[2] < q.t_next[a]) a = 2;
  if (q.t_next[a] > q.t1) return false;
  q.v[a] += q.stp[a];
  if (q.v[a] < 0 || q.v[a] >= dims[a]) return false;
  q.t_next[a] += q.t_delta[a];
  return true;
}

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
  PvDda q;
  if (!pv_dda_begin(o, d, t_min, t_max, q)) return -1;
  const ivec3 dims = g_dims.xyz;
  const float r = g_lo_r.w;
  const uint target = steps;  // cells to replay before testing discs again
  uint taken = 0u, spent = 0u, k = 0u, cell_b = 0u, i = 0u, e = 0u;
  if (target == 0u) {
    k = pv_hash(q.v, dims);
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
    if (!pv_dda_step(q, dims)) return -1;
    ++taken;
    if (taken >= target) {
      k = pv_hash(q.v, dims);
      cell_b = texelFetch(cell_start, int(k)).x;
      i = cell_b + (taken == target ? disc : 0u);
      e = texelFetch(cell_start, int(k + 1u)).x;
    }
  }
  return -1;
}

// Whether pv_ray_disc's hit lies in [t_min, t_max]: its operations without its branches, which a
// SIMD device would run masked one after another (a parallel dn of 0 makes t infinite or NaN, and
// every comparison with it false, as the early return does).
bool pv_ray_disc_hits(vec3 o, vec3 d, vec3 c, vec3 n, float r, float t_min, float t_max) {
  const float dn = dot(d, n);
  const float t = dot(c - o, n) / dn;
  const vec3 q = o + t * d - c;
  // Named first: `&&` with a call on its right is compiled to branches.
  const bool facing = !(abs(dn) < 1e-8), ahead = t >= 0.0, inside = dot(q, q) <= r * r, in_range = t >= t_min && t <= t_max;
  return facing && ahead && inside && in_range;
}

// Discs a lane tests per iteration of pv_march_lanes: fewer iterations (each pays for the budget's
// count and the subgroup's vote) against lanes idle in a cell's last iteration. A part of the unrolled
// body that no lane needs is skipped whole (its branch is uniform then).
const uint kPvMarchUnroll = 4u;

// pv_march with the ray's discs tested across the subgroup's lanes (the CPU's any_disc_hit, lanes
// on discs): every lane of the subgroup calls it with the same ray and place, and lane l tests discs
// i + u gl_SubgroupSize + l of each iteration. The DDA runs alike in every lane (the same operations
// on the same values), and a cell ends the ray when any lane's disc is hit, so every branch is
// uniform and every iteration keeps the lanes busy while a cell has discs left. The cells a ray
// visits hold hundreds of discs in the scenes measured (on `character`, 24053 proxies in 85 of 512
// cells); one ray per lane makes the SIMD batch wait in each cell on the lane with the most discs,
// while the others have none there. `spent` counts the caller's iterations with this function's (the
// driver's limit is per batch); the budget and the saved place work as in pv_march.
int pv_march_lanes(vec3 o, vec3 d, float t_min, float t_max, inout uint steps, inout uint disc, uint budget, inout uint spent) {
  if (g_counts.x == 0u) return -1;
  PvDda q;
  if (!pv_dda_begin(o, d, t_min, t_max, q)) return -1;
  const ivec3 dims = g_dims.xyz;
  const float r = g_lo_r.w;
  const uint lanes = gl_SubgroupSize, lane = gl_SubgroupInvocationID;
  const uint target = steps;  // cells to replay before testing discs again
  uint taken = 0u;
  for (;;) {
    if (taken >= target) {
      const uint k = pv_hash(q.v, dims);
      const uint cell_b = texelFetch(cell_start, int(k)).x, e = texelFetch(cell_start, int(k + 1u)).x;
      for (uint i = cell_b + (taken == target ? disc : 0u); i < e; i += kPvMarchUnroll * lanes) {
        if (++spent > budget) {
          steps = taken;
          disc = i - cell_b;
          return -2;
        }
        bool hit = false;
        [[unroll]] for (uint u = 0u; u < kPvMarchUnroll; ++u) {
          const uint j = i + u * lanes + lane;
          if (j < e) {
            const bool h = pv_ray_disc_hits(o, d, texelFetch(discs, int(4u * j)).xyz, texelFetch(discs, int(4u * j + 1u)).xyz, r, t_min, t_max);
            hit = hit || h;
          }
        }
        if (subgroupAny(hit)) return int(k);
      }
      if (++spent > budget) {
        // Every disc of this cell tested: the next call resumes at its step.
        steps = taken;
        disc = e - cell_b;
        return -2;
      }
    } else if (++spent > budget) {
      return -2;  // still replaying: the saved place stands
    }
    if (!pv_dda_step(q, dims)) return -1;
    ++taken;
  }
  return -1;
}

#endif
