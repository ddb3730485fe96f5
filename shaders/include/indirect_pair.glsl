// One proxy's step of image_splat's indirect accumulation (paper 000 section 5), shared by
// accumulate_indirect.comp (a receiver's proxy list, one invocation per receiver) and
// splat_indirect.frag (one rasterised sphere of influence at one receiver, Figure 3), so that both
// sum the same floats. The arithmetic follows IndirectEvaluator::accumulate and Impl::pair
// (techniques/image_splat/indirect_evaluator.cpp) step by step, on the evaluator's own table floats
// (IndirectEvaluator::tables(), uploaded: the M and Q blocks are never recomputed here); the basis
// is the SHEXP kernel's recurrence.
//
// Expects, declared before the include: the specialisation constants N (indirect order), RULE and
// OP, the texel buffers vis, dfac, mtab and qrot, the uniform block `consts_v` (vec4
// [kIndConstFloats / 4]; image_splat_indirect_shared.h), and softgi_shared.h, texels.glsl,
// sh_basis.glsl, accum_math.glsl, replacement_rule.glsl and image_splat_indirect_shared.h included.
#ifndef SOFTGI_INDIRECT_PAIR_GLSL
#define SOFTGI_INDIRECT_PAIR_GLSL

// L~ and the band factors, the same for every pair: a uniform block indexed by constants (every use
// below sits in an unrolled loop), which a SIMD device reads once for all lanes, where a texel fetch
// at one address costs llvmpipe a fetch per lane (and a pair reads 3 n^2 + n of them).
float ind_const(uint i) { return consts_v[i >> 2u][i & 3u]; }
float lt(uint k, uint c) { return ind_const(3 * k + c); }
float vh(uint l) { return ind_const(3 * N * N + l); }
float hc(uint l) { return ind_const(3 * N * N + N + l); }
uint sh_index(uint l, int m) { return uint(int(l * l + l) + m); }

// Paper 000 eqs. 16-17, Impl::pair's exact branch: I . H(N) = (M(theta) R L~) . H(R N) with
// R = Ry(-beta) Rz(-phi) taking d to +z and Ry(a) = Q Rz(a) Q^T. Every band of R L~ depends on that
// band of L~ only, so the rotation runs band by band (the CPU rotates all bands per step: the same
// operations per coefficient) and only R L~ itself is kept. M (eq. 16, per row its m-blocks) is
// interpolated between rows k and k + 1 inside the sum, one entry at a time, as the CPU's Mi but
// without holding an interpolated row (up to 146 floats at order 6) per invocation. The three
// channels are the CPU's per-channel loops side by side.
vec3 exact_pair(const vec3 d, const vec3 Nrm, const uint k, const float fr) {
  const float rho = sqrt(d.x * d.x + d.y * d.y);
  const float cphi = rho > 1e-12 ? d.x / rho : 1.0, sphi = rho > 1e-12 ? d.y / rho : 0.0;
  const float cb = d.z, sb = rho;
  // cos, sin of m (-phi) and m (-beta), the CPU's `multiples` with s = -sin.
  const float sp = -sphi, sbn = -sb;
  float cmp[kAccumMaxOrder], smp[kAccumMaxOrder], cmb[kAccumMaxOrder], smb[kAccumMaxOrder];
  cmp[0] = 1.0;
  smp[0] = 0.0;
  cmb[0] = 1.0;
  smb[0] = 0.0;
  [[unroll]] for (uint m = 1; m < N; ++m) {
    cmp[m] = cmp[m - 1] * cphi - smp[m - 1] * sp;
    smp[m] = smp[m - 1] * cphi + cmp[m - 1] * sp;
    cmb[m] = cmb[m - 1] * cb - smb[m - 1] * sbn;
    smb[m] = smb[m - 1] * cb + cmb[m - 1] * sbn;
  }
  // N' = R N; H(N')_lm = hc_l y_lm(N') (H is zonal about N: R H(N) = H(R N)).
  const float x1 = cphi * Nrm.x + sphi * Nrm.y, y1 = -sphi * Nrm.x + cphi * Nrm.y, z1 = Nrm.z;
  const vec3 np = vec3(cb * x1 - sb * z1, y1, sb * x1 + cb * z1);
  float hp[kAccumMaxCoeffs];
  sh_basis_eval(np, hp);
  [[unroll]] for (uint q = 0; q < N * N; ++q) hp[q] *= hc(kShBand[q]);
  // f = R L~ = Q Rz(-beta) Q^T Rz(-phi) L~, band by band; band l of Q at the running offset
  // (TableView::qoff, checked on the host).
  vec3 f[kAccumMaxOrder * kAccumMaxOrder];
  uint qo = 0;
  [[unroll]] for (uint l = 0; l < N; ++l) {
    const uint w = 2 * l + 1, base = l * l;
    vec3 t[2 * kAccumMaxOrder - 1], g[2 * kAccumMaxOrder - 1];
    [[unroll]] for (uint i = 0; i < w; ++i) t[i] = vec3(lt(base + i, 0), lt(base + i, 1), lt(base + i, 2));
    [[unroll]] for (uint m = 1; m <= l; ++m) {  // rotate_z(-phi): (A, B) = (f_lm, f_l,-m)
      const vec3 a = t[l + m], b = t[l - m];
      t[l + m] = a * cmp[m] - b * smp[m];
      t[l - m] = a * smp[m] + b * cmp[m];
    }
    [[unroll]] for (uint i = 0; i < w; ++i) {  // Q^T
      vec3 s = vec3(0.0);
      [[unroll]] for (uint j = 0; j < w; ++j) s += texel1(qrot, qo + j * w + i) * t[j];
      g[i] = s;
    }
    [[unroll]] for (uint m = 1; m <= l; ++m) {  // rotate_z(-beta)
      const vec3 a = g[l + m], b = g[l - m];
      g[l + m] = a * cmb[m] - b * smb[m];
      g[l - m] = a * smb[m] + b * cmb[m];
    }
    [[unroll]] for (uint i = 0; i < w; ++i) {  // Q
      vec3 s = vec3(0.0);
      [[unroll]] for (uint j = 0; j < w; ++j) s += texel1(qrot, qo + i * w + j) * g[j];
      f[base + i] = s;
    }
    qo += w * w;
  }
  // sum_m sum_a H'_(|m|+a),m sum_b M_ab f_(|m|+b),m over the m-blocks; block m at the running
  // offset (TableView::moff), a row is mrow floats (checked on the host).
  uint mrow = 0;
  [[unroll]] for (int m = -(int(N) - 1); m <= int(N) - 1; ++m) mrow += (N - uint(abs(m))) * (N - uint(abs(m)));
  const uint r0 = k * mrow, r1 = r0 + mrow;
  vec3 acc = vec3(0.0);
  uint mo = 0;
  [[unroll]] for (int m = -(int(N) - 1); m <= int(N) - 1; ++m) {
    const uint am = uint(abs(m)), w = N - am;
    [[unroll]] for (uint a = 0; a < w; ++a) {
      vec3 r = vec3(0.0);
      [[unroll]] for (uint b = 0; b < w; ++b) {
        const uint e = mo + a * w + b;
        const float m0 = texel1(mtab, r0 + e);
        r += (m0 + fr * (texel1(mtab, r1 + e) - m0)) * f[sh_index(am + b, m)];
      }
      acc += hp[sh_index(am + a, m)] * r;
    }
    mo += w * w;
  }
  return acc;
}

// Proxy `sph` (centre, radius) with albedo / pi `alb` at receiver (P, Nrm): false where the pair
// does not count (reach > 0 and |c - p| >= reach r; the replacement rule eliminated the proxy; or
// the receiver lies outside the adjusted sphere's sphere of influence eta r, eta > 0); else albedo / pi (I . H(N_p)) in `light` and omega_i (eq. 2)
// in `omega`, the terms of the receiver's two sums.
bool indirect_pair(const vec4 sph, const vec3 alb, const vec3 P, const vec3 Nrm, const float eta, const float reach, const float scale,
                   const uint rows, out vec3 light, out float omega) {
  if (reach > 0.0 && !(length(sph.xyz - P) < reach * sph.w)) return false;  // IndirectSetup::reach
  // Self-shadowing replacement rules (paper 004 section 6.2), as in the shadow pass.
  const vec4 s = apply_replacement_rule(RULE, P, Nrm, sph.xyz, sph.w);
  if (!(s.w > 0.0)) return false;
  const vec3 dv = s.xyz - P;
  const float dist = sqrt(dot(dv, dv));
  if (!(dist > 0.0)) return false;
  if (eta > 0.0 && dist >= eta * s.w) return false;  // outside the sphere of influence (section 4.1)
  const float alpha = min(1.0, s.w / dist);  // eq. 1
  const float u = accum_asin01(alpha) * scale;
  const vec3 d = dv / dist;
  int k = min(int(min(u, float(rows - 1))), int(rows) - 2);
  k = max(k, 0);
  const float fr = u - float(k);
  const uint row = uint(k) * 2u * N;
  // omega_i = sqrt(4pi) V_i,0 = F_0 (eq. 2 through the DC term).
  omega = texel1(vis, row) + fr * texel1(vis, row + 1);
  if (OP == kIndOpExact) {
    light = alb * exact_pair(d, Nrm, uint(k), fr);  // eqs. 16-17
    return true;
  }
  // V . H(N) = sum_l F_l vh_l P_l(d . N) (addition theorem).
  float F[kAccumMaxOrder];
  [[unroll]] for (uint l = 0; l < N; ++l) F[l] = texel1(vis, row + 2 * l) + fr * texel1(vis, row + 2 * l + 1);
  const float t = clamp(dot(d, Nrm), -1.0, 1.0);
  float p0 = 1.0, p1 = t;
  float vdoth = F[0] * vh(0) + (N > 1 ? F[1] * vh(1) * t : 0.0);
  [[unroll]] for (uint l = 2; l < N; ++l) {
    const float p2 = ((2.0 * float(l) - 1.0) * t * p1 - (float(l) - 1.0) * p0) / float(l);
    vdoth += F[l] * vh(l) * p2;
    p0 = p1;
    p1 = p2;
  }
  // Per-band factors: eq. 13 (-1)^l (L~ at -d), or eq. 15's interpolated D factors.
  float fac[kAccumMaxOrder];
  if (OP == kIndOpPoint) {
    [[unroll]] for (uint l = 0; l < N; ++l) fac[l] = (l & 1u) != 0u ? -1.0 : 1.0;
  } else {
    const uint d0 = uint(k) * N;
    [[unroll]] for (uint l = 0; l < N; ++l)
      fac[l] = texel1(dfac, d0 + l) + fr * (texel1(dfac, d0 + N + l) - texel1(dfac, d0 + l));
  }
  // B_l = sum_m y_lm(d) L~_lm per channel; kappa = sum_l fac_l B_l. Basis by the SHEXP recurrence.
  float y[kAccumMaxCoeffs];
  sh_basis_eval(d, y);
  vec3 B[kAccumMaxOrder];
  [[unroll]] for (uint l = 0; l < N; ++l) B[l] = vec3(0.0);
  [[unroll]] for (uint q = 0; q < N * N; ++q) B[kShBand[q]] += y[q] * vec3(lt(q, 0), lt(q, 1), lt(q, 2));
  vec3 kap = vec3(0.0);
  [[unroll]] for (uint l = 0; l < N; ++l) kap += fac[l] * B[l];
  light = alb * (kap * vdoth);  // diffuse proxy: radiance albedo / pi L~
  return true;
}

#endif
