// The SHEXP accumulation kernel, written once over a SIMD wrapper V (see kernel.cpp). Deliberately
// without include guard: kernel.cpp includes it once per instruction set, each time inside a
// namespace and a `#pragma GCC target` region, so that every function defined here is compiled for
// that instruction set only and dispatched at run time. Expects in scope: ZhTable, BlockerList,
// ReceiverSoA, ReplacementRule, BasisConsts basis_consts(), kAsin[8].

// asin(x) for x in [0, 1]: Abramowitz & Stegun 4.4.46, |error| <= 2e-8 (float rounding dominates),
// well below the table's spacing of 0.35 degrees at 256 samples.
template <class V>
inline typename V::F asin01(typename V::F x) {
  using F = typename V::F;
  // Estrin's scheme: a dependency chain of 3 multiply-adds instead of Horner's 7.
  const F x2 = V::mul(x, x), x4 = V::mul(x2, x2);
  const F p01 = V::fma(V::set(kAsin[1]), x, V::set(kAsin[0])), p23 = V::fma(V::set(kAsin[3]), x, V::set(kAsin[2]));
  const F p45 = V::fma(V::set(kAsin[5]), x, V::set(kAsin[4])), p67 = V::fma(V::set(kAsin[7]), x, V::set(kAsin[6]));
  const F p = V::fma(V::fma(p67, x2, p45), x4, V::fma(p23, x2, p01));
  const F omx = V::max(V::sub(V::set(1.0f), x), V::set(0.0f));
  const F s = V::mul(omx, V::rsqrt(V::max(omx, V::set(1e-30f))));  // sqrt(1 - x), 0 at x = 1
  return V::max(V::fnma(s, p, V::set(static_cast<float>(sh::kPi / 2))), V::set(0.0f));
}

// One blocker seen from V::W receivers (p = px, py, pz, nx, ny, nz): the replacement rules
// (section 6.2), the angular radius and direction of the adjusted sphere, and the table row F(theta)
// of eq. 34 (fl[N], not yet weighted). Returns sin(theta), 0 on lanes where the sphere is eliminated.
template <class V, int N>
__attribute__((always_inline)) inline typename V::F blocker_view(const ZhTable& table, ReplacementRule rule, const typename V::F* p,
                                                                 float bx, float by, float bz, float rj, typename V::F* fl,
                                                                 typename V::F& sx, typename V::F& sy, typename V::F& sz,
                                                                 typename V::F* u_out = nullptr) {
  using F = typename V::F;
  using I = typename V::I;
  const F &px = p[0], &py = p[1], &pz = p[2], &nx = p[3], &ny = p[4], &nz = p[5];
  const F zero = V::set(0.0f), one = V::set(1.0f), half = V::set(0.5f), tiny = V::set(1e-30f);
  const F r = V::set(rj);
  const F dx = V::sub(V::set(bx), px), dy = V::sub(V::set(by), py), dz = V::sub(V::set(bz), pz);
  const F h = V::fma(dx, nx, V::fma(dy, ny, V::mul(dz, nz)));  // centre height above T_p
  const F d2 = V::fma(dx, dx, V::fma(dy, dy, V::mul(dz, dz)));
  const F a2 = V::max(V::fnma(h, h, d2), zero);  // squared distance along T_p from p to q1

  // Replacement rules (section 6.2, accumulation.hpp): the adjusted sphere is tangent to T_p at
  // q1 with radius rho, so seen from p its centre is at (in-plane offset) + hh N.
  F rho = r, hh = h;
  // The rules leave a sphere entirely in front of every lane's tangent plane unaltered: the common
  // case of distant blockers costs one compare.
  if (rule != ReplacementRule::Off && !V::all(V::ge(h, r))) {
    const F r2 = V::set(rj * rj);
    const auto inside = V::lt(d2, r2);
    const F rin = V::max(h, zero);
    const F rout = V::max(V::mul(half, V::add(h, r)), zero);
    // d = sqrt(r^2 - h^2) and (|p - q1| - d)/max(d, dmin) through reciprocal square roots (no
    // divisions or square roots in the loop). Below dmin the ratio only needs to be large.
    const F dmin = V::set(1e-6f * rj);
    const F q = V::max(V::fnma(h, h, r2), zero);
    const F rq = V::rsqrt(V::max(q, V::set(1e-12f * rj * rj)));
    const F dd = V::mul(q, rq);
    const F dist = V::mul(a2, V::rsqrt(V::max(a2, tiny)));
    const F ratio = V::mul(V::sub(dist, dd), rq);
    if (rule == ReplacementRule::Continuous) {
      const F t = V::select(inside, zero, V::min(V::max(ratio, zero), one));
      rho = V::fma(t, V::sub(rout, rin), rin);
    } else if (rule == ReplacementRule::Clamped) {
      const F t = V::min(V::max(ratio, zero), one);
      rho = V::select(inside, rin, V::mul(t, rout));
    } else if (rule == ReplacementRule::InsideOnly) {
      rho = rin;  // the lanes outside S are restored below
    } else {
      const F a = V::select(V::lt(dmin, dd), V::max(ratio, one), one);
      rho = V::select(inside, rin, V::mul(a, rout));
    }
    const auto front = V::ge(h, r);
    rho = V::select(front, r, rho);
    hh = V::select(front, h, rho);
    if (rule == ReplacementRule::InsideOnly) {
      // Any sphere that p is outside of is left whole.
      const auto outside = V::ge(d2, r2);
      rho = V::select(outside, r, rho);
      hh = V::select(outside, h, hh);
    }
  }
  // v = P' - p = d + (hh - h) N. Its length is taken from v itself (not from a2 + hh^2) so that
  // s = v/|v| stays a unit vector under the cancellation of a receiver on its own sphere.
  const F dh = V::sub(hh, h);
  const F vx = V::fma(dh, nx, dx), vy = V::fma(dh, ny, dy), vz = V::fma(dh, nz, dz);
  const F inv = V::rsqrt(V::max(V::fma(vx, vx, V::fma(vy, vy, V::mul(vz, vz))), tiny));
  // eq. 34: asin(r/|P - p|); exactly 0 for an eliminated sphere (the polynomial leaves ~1e-7 there)
  // and for one that rounding shrank below 1e-6 of its radius (its direction is then noise).
  const F st = V::select(V::lt(V::set(1e-6f * rj), rho), V::min(V::mul(rho, inv), one), zero);
  const F theta = V::select(V::lt(zero, st), asin01<V>(st), zero);

  // F(theta) by linear interpolation of the table (rows: (value, slope) per band).
  const F u = V::mul(theta, V::set(table.scale));
  const I k = V::iclamp(V::trunc(u), 0, table.rows - 2);
  const F fr = V::sub(u, V::to_float(k));
  V::template fetch_bands<N>(table, k, fr, fl);
  if (u_out) *u_out = u;

  // s = direction to the adjusted centre.
  sx = V::mul(vx, inv);
  sy = V::mul(vy, inv);
  sz = V::mul(vz, inv);
  return st;
}

// One block of V::W receivers (lane arrays lanes[0..5] = px, py, pz, nx, ny, nz) against every
// blocker of `b`; writes the N*N accumulated coefficients, coefficient-major, to out[c * W + lane].
template <class V, int N>
void kernel_block(const ZhTable& table, ReplacementRule rule, const float (*lanes)[V::W], const BlockerList& b,
                  float* out) {
  using F = typename V::F;
  constexpr int N2 = N * N;
  F p[6];
  for (int a = 0; a < 6; ++a) p[a] = V::load(lanes[a]);
  F acc[N2];
#pragma GCC unroll 64
  for (int c = 0; c < N2; ++c) acc[c] = V::set(0.0f);

  const BasisConsts& bc = basis_consts();
  const F zero = V::set(0.0f), one = V::set(1.0f);
  const float *bx = b.cx.data(), *by = b.cy.data(), *bz = b.cz.data(), *br = b.r.data(), *bw = b.w.data();
  const std::size_t count = b.size();

#pragma GCC unroll 2
  for (std::size_t j = 0; j < count; ++j) {
    F fl[N], sx, sy, sz;
    blocker_view<V, N>(table, rule, p, bx[j], by[j], bz[j], br[j], fl, sx, sy, sz);
#pragma GCC unroll 16
    for (int l = 0; l < N; ++l) fl[l] = V::mul(fl[l], V::set(bw[j * N + l]));  // W of eq. 38

    // Real SH by the polynomial recurrence: y_{l,+-m} = Q_l^m(z) {C_m, S_m}(x, y), C_m + i S_m = (x + i y)^m.
    F C[N], S[N];
    C[0] = one;
    S[0] = zero;
#pragma GCC unroll 16
    for (int m = 1; m < N; ++m) {
      C[m] = V::fnma(S[m - 1], sy, V::mul(C[m - 1], sx));
      S[m] = V::fma(S[m - 1], sx, V::mul(C[m - 1], sy));
    }
#pragma GCC unroll 16
    for (int m = 0; m < N; ++m) {
      F q_prev = zero, q = V::set(bc.qmm[m]);  // Q_m^m
#pragma GCC unroll 16
      for (int l = m; l < N; ++l) {
        if (l == m + 1) {
          q_prev = q;
          q = V::mul(V::set(bc.a1[m]), V::mul(sz, q));
        } else if (l > m + 1) {
          F next = V::fnma(V::set(bc.B[l][m]), q_prev, V::mul(V::set(bc.A[l][m]), V::mul(sz, q)));
          q_prev = q;
          q = next;
        }
        const int i0 = l * l + l;
        if (m == 0) {
          acc[i0] = V::fma(fl[l], q, acc[i0]);
        } else {
          const F g = V::mul(fl[l], q);
          acc[i0 + m] = V::fma(g, C[m], acc[i0 + m]);
          acc[i0 - m] = V::fma(g, S[m], acc[i0 - m]);
        }
      }
    }
  }
#pragma GCC unroll 64
  for (int c = 0; c < N2; ++c) V::store(out + c * V::W, acc[c]);
}

// Receivers i0 .. i0 + cnt - 1 of rec (0 < cnt <= W) as the lane arrays px, py, pz, nx, ny, nz of a
// block; the lanes past cnt repeat the last receiver, so that a short block computes a real
// receiver's values in lanes whose results are dropped.
template <int W>
inline void receiver_lanes(const ReceiverSoA& rec, std::size_t i0, std::size_t cnt, float (*lanes)[W]) {
  const float* src[6] = {rec.px.data(), rec.py.data(), rec.pz.data(), rec.nx.data(), rec.ny.data(), rec.nz.data()};
  for (int a = 0; a < 6; ++a)
    for (int k = 0; k < W; ++k) lanes[a][k] = src[a][i0 + (static_cast<std::size_t>(k) < cnt ? k : cnt - 1)];
}

template <class V, int N>
void kernel_range(const ZhTable& table, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin, std::size_t end,
                  const BlockerList& b, float* out) {
  constexpr int W = V::W, N2 = N * N;
  alignas(64) float lanes[6][W];
  alignas(64) float res[N2 * W];
  for (std::size_t i0 = begin; i0 < end; i0 += W) {
    const std::size_t cnt = end - i0 < static_cast<std::size_t>(W) ? end - i0 : static_cast<std::size_t>(W);
    receiver_lanes<W>(rec, i0, cnt, lanes);
    kernel_block<V, N>(table, rule, lanes, b, res);
    for (std::size_t k = 0; k < cnt; ++k)
      for (int c = 0; c < N2; ++c) out[(i0 + k) * N2 + c] = res[c * W + k];
  }
}

inline void kernel_dispatch(int order, const ZhTable& table, ReplacementRule rule, const ReceiverSoA& rec,
                            std::size_t begin, std::size_t end, const BlockerList& b, float* out) {
  switch (order) {
    case 3: kernel_range<Vec, 3>(table, rule, rec, begin, end, b, out); return;
    case 4: kernel_range<Vec, 4>(table, rule, rec, begin, end, b, out); return;
    case 5: kernel_range<Vec, 5>(table, rule, rec, begin, end, b, out); return;
    case 6: kernel_range<Vec, 6>(table, rule, rec, begin, end, b, out); return;
    case 7: kernel_range<Vec, 7>(table, rule, rec, begin, end, b, out); return;
    case 8: kernel_range<Vec, 8>(table, rule, rec, begin, end, b, out); return;
    default: break;
  }
}
