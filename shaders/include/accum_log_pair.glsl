// One blocker's step of SHEXP's log-visibility accumulation (paper 004 eqs. 8, 34, 38) with the
// self-shadowing replacement rules of section 6.2, shared by accumulate_log.comp (a receiver's
// blocker list, one invocation per receiver) and image_splat's splat_log.frag (one rasterised
// sphere of influence at one receiver, paper 000 Figure 3), so that both sum the same floats. The
// arithmetic follows the CPU kernel (techniques/shexp/kernel_body.hpp, blocker_view and
// kernel_block) step by step.
//
// Expects, declared before the include: the specialisation constants N (order) and RULE, W4 (vec4s
// of band weights per blocker), the texel buffers weights4 (band weights, rows of W4 vec4s) and
// table2 (the table's (value, slope) per row and band), sh_basis.glsl and accum_math.glsl.
#ifndef SOFTGI_ACCUM_LOG_PAIR_GLSL
#define SOFTGI_ACCUM_LOG_PAIR_GLSL

// Blocker `sphere` (centre, radius) with band weights at row `weight_row` of weights4, seen from
// receiver (P, Nrm). cut > 0: the pair counts only where |c - p| < cut r (image_splat's per-pair
// sphere-of-influence cut, paper 000 section 4.1), checked before the rules; false where it does
// not count. Else sh_dir is the unit direction to the (replaced) blocker and fl[l] = W_l F_l(theta)
// (eq. 38) for l < N; the caller adds fl[l] y_lm(sh_dir).
bool accum_log_pair(vec4 sphere, uint weight_row, vec3 P, vec3 Nrm, float cut, float scale, uint rows, out vec3 sh_dir,
                    out float fl[kAccumMaxOrder]) {
  const float r = sphere.w;
  const vec3 d = sphere.xyz - P;
  if (cut > 0.0 && !(length(d) < cut * r)) return false;  // image_splat_core.cpp accumulate_log_range
  const float h = dot(d, Nrm);  // centre height above the tangent plane T_p
  const float d2 = dot(d, d);
  const float a2 = max(d2 - h * h, 0.0);  // squared in-plane distance from p to q1
  // Replacement rules (section 6.2; techniques/common/accumulation.hpp): a sphere tangent to T_p at q1, radius rho.
  float rho = r, hh = h;
  if (RULE != kRuleOff && h < r) {
    const float r2 = r * r;
    const bool inside = d2 < r2;
    const float rin = max(h, 0.0);
    const float rout = max(0.5 * (h + r), 0.0);
    const float dmin = 1e-6 * r;
    const float q = max(r2 - h * h, 0.0);
    const float rq = inversesqrt(max(q, 1e-12 * r * r));
    const float dd = q * rq;
    const float dist = a2 * inversesqrt(max(a2, 1e-30));
    const float ratio = (dist - dd) * rq;
    if (RULE == kRuleContinuous) {
      const float t = inside ? 0.0 : clamp(ratio, 0.0, 1.0);
      rho = t * (rout - rin) + rin;
    } else if (RULE == kRuleClamped) {
      const float t = clamp(ratio, 0.0, 1.0);
      rho = inside ? rin : t * rout;
    } else if (RULE == kRuleInsideOnly) {
      rho = inside ? rin : r;  // outside: the sphere whole (below, hh stays h)
    } else {
      const float a = dmin < dd ? max(ratio, 1.0) : 1.0;
      rho = inside ? rin : a * rout;
    }
    hh = (RULE == kRuleInsideOnly && !inside) ? h : rho;
  }
  const vec3 v = d + (hh - h) * Nrm;
  const float inv = inversesqrt(max(dot(v, v), 1e-30));
  const float st = (1e-6 * r < rho) ? min(rho * inv, 1.0) : 0.0;
  const float theta = st > 0.0 ? accum_asin01(st) : 0.0;
  const float u = theta * scale;
  const int k = clamp(int(u), 0, int(rows) - 2);
  const float fr = u - float(k);
  const uint row = uint(k) * N;
  float w[4u * ((kAccumMaxOrder + 3u) / 4u)];
  [[unroll]] for (uint q = 0; q < W4; ++q) {
    const vec4 x = texelFetch(weights4, int(weight_row * W4 + q));
    w[4u * q] = x.x;
    w[4u * q + 1u] = x.y;
    w[4u * q + 2u] = x.z;
    w[4u * q + 3u] = x.w;
  }
  [[unroll]] for (uint l = 0; l < N; ++l) {
    const vec2 t = texelFetch(table2, int(row + l)).xy;  // (value, slope) of band l
    fl[l] = (fr * t.y + t.x) * w[l];  // W of eq. 38
  }
  sh_dir = v * inv;
  return true;
}

// The basis by recurrence, fl[l] y_lm(sh_dir) added to the caller's acc[] as kernel_block adds them:
// after accum_log_pair, `{ SH_BASIS_UNROLLED(N) }` with acc, fl and sh_dir in scope.
#define SH_BASIS_PUT(l, m, q)                       \
  if ((m) == 0u) {                                  \
    acc[(l) * (l) + (l)] += fl[l] * (q);            \
  } else {                                          \
    const float g = fl[l] * (q);                    \
    acc[(l) * (l) + (l) + (m)] += g * sh_C[m];      \
    acc[(l) * (l) + (l) - (m)] += g * sh_S[m];      \
  }

#endif
