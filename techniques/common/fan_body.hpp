// sphere_fan: one receiver against many spheres, a sphere per lane, written once over a SIMD
// wrapper V. No include guard, for the reason in kernel_body.hpp: kernel.cpp includes it once per
// instruction set, after kernel_body.hpp and batch_body.hpp (asin01, basis_soa). Expects in scope:
// ZhTable, SphereFan, ReplacementRule.

// W spheres [j0, j0 + cnt) of `s` seen from the receiver (p, n); writes sphere_fan's outputs for
// those spheres only. The lanes past cnt repeat the last sphere and are not stored.
template <class V, int N>
void fan_block(const ZhTable& log, ReplacementRule rule, const float* pn, const SphereFan& s, std::size_t j0, std::size_t cnt,
               const float* zh_factor, float* g, float* key, std::uint8_t* alive, float* rgb) {
  using F = typename V::F;
  using I = typename V::I;
  constexpr int W = V::W, N2 = N * N;
  alignas(64) float in[4][W];
  alignas(64) int id[W];
  for (int l = 0; l < W; ++l) {
    const std::size_t j = j0 + (static_cast<std::size_t>(l) < cnt ? l : cnt - 1);
    in[0][l] = s.cx[j];
    in[1][l] = s.cy[j];
    in[2][l] = s.cz[j];
    in[3][l] = s.r[j];
    id[l] = s.id ? s.id[j] : 0;
  }
  const F cx = V::load(in[0]), cy = V::load(in[1]), cz = V::load(in[2]), r = V::load(in[3]);
  const F px = V::set(pn[0]), py = V::set(pn[1]), pz = V::set(pn[2]);
  const F nx = V::set(pn[3]), ny = V::set(pn[4]), nz = V::set(pn[5]);
  const F zero = V::set(0.0f), one = V::set(1.0f), tiny = V::set(1e-30f);
  const F half_pi = V::set(static_cast<float>(sh::kPi / 2));

  // The replacement rules, step by step as apply_replacement_rule (paper 004 section 6.2), with the
  // square root and division that the accumulation kernel replaces by reciprocal square roots: the
  // adjusted sphere decides whether a light is eliminated, so it follows the scalar definition.
  F ax = cx, ay = cy, az = cz, rho = r;
  if (rule != ReplacementRule::Off) {
    const F cpx = V::sub(cx, px), cpy = V::sub(cy, py), cpz = V::sub(cz, pz);
    const F h = V::fma(cpx, nx, V::fma(cpy, ny, V::mul(cpz, nz)));
    const auto front = V::ge(h, r);
    if (!V::all(front)) {
      const F r2 = V::mul(r, r);
      const auto inside = V::lt(V::fma(cpx, cpx, V::fma(cpy, cpy, V::mul(cpz, cpz))), r2);
      const F q1x = V::fnma(h, nx, cx), q1y = V::fnma(h, ny, cy), q1z = V::fnma(h, nz, cz);
      const F rin = V::max(h, zero);
      const F rout = V::max(V::mul(V::set(0.5f), V::add(h, r)), zero);
      const F d = V::sqrt(V::max(V::fnma(h, h, r2), zero));
      const F dmin = V::mul(V::set(1e-6f), r);
      const F ex = V::sub(px, q1x), ey = V::sub(py, q1y), ez = V::sub(pz, q1z);
      const F along = V::sqrt(V::fma(ex, ex, V::fma(ey, ey, V::mul(ez, ez))));
      const F ratio = V::div(V::sub(along, d), V::max(d, dmin));
      F adj = rin;
      if (rule == ReplacementRule::Continuous) {
        const F t = V::select(inside, zero, V::min(V::max(ratio, zero), one));
        adj = V::fma(t, V::sub(rout, rin), rin);
      } else if (rule == ReplacementRule::Clamped) {
        adj = V::select(inside, rin, V::mul(V::min(V::max(ratio, zero), one), rout));
      } else if (rule == ReplacementRule::Printed) {
        const F a = V::select(V::lt(dmin, d), V::max(one, ratio), one);
        adj = V::select(inside, rin, V::mul(a, rout));
      }
      adj = V::select(V::lt(dmin, adj), adj, zero);  // below 1e-6 of its radius: eliminated
      ax = V::select(front, cx, V::fma(adj, nx, q1x));
      ay = V::select(front, cy, V::fma(adj, ny, q1y));
      az = V::select(front, cz, V::fma(adj, nz, q1z));
      rho = V::select(front, r, adj);
      if (rule == ReplacementRule::InsideOnly) {  // a sphere that p is outside of is left whole
        ax = V::select(inside, ax, cx);
        ay = V::select(inside, ay, cy);
        az = V::select(inside, az, cz);
        rho = V::select(inside, rho, r);
      }
    }
  }

  // The adjusted sphere seen from p: alive where p is outside it; eq. 34 with theta = asin(rho/dist).
  const F vx = V::sub(ax, px), vy = V::sub(ay, py), vz = V::sub(az, pz);
  const F dist = V::sqrt(V::fma(vx, vx, V::fma(vy, vy, V::mul(vz, vz))));
  const auto live = V::land(V::lt(zero, rho), V::lt(rho, dist));
  const F inv = V::div(one, V::max(dist, tiny));
  const F theta = asin01<V>(V::min(V::mul(rho, inv), one));
  const F u = V::mul(theta, V::set(log.scale));
  const I k = V::iclamp(V::trunc(u), 0, log.rows - 2);
  F fl[N];
  V::template fetch_bands<N>(log, k, V::sub(u, V::to_float(k)), fl);
  alignas(64) float y[N2 * W];
  basis_soa<V>(N, V::mul(vx, inv), V::mul(vy, inv), V::mul(vz, inv), y);
  for (int l = 0; l < N; ++l)
    for (int c = l * l; c < (l + 1) * (l + 1); ++c) V::store(y + c * W, V::mul(fl[l], V::load(y + c * W)));
  alignas(64) float kv[W], av[W];
  V::store(kv, V::sub(dist, rho));
  V::store(av, V::select(live, one, zero));
  for (std::size_t l = 0; l < cnt; ++l) {
    const std::size_t j = j0 + l;
    key[j] = kv[l];
    alive[j] = av[l] != 0.0f ? 1 : 0;
    float* gj = g + j * N2;
    for (int c = 0; c < N2; ++c) gj[c] = y[c * W + l];
  }
  if (!s.L) return;

  // Paper 001 eq. 18 over the sphere as given: theta = asin(r/D) (pi/2 from inside), the direction
  // from its centre to p in its own frame (R^T, R column-major), the weight table's bands at theta.
  const F dx = V::sub(px, cx), dy = V::sub(py, cy), dz = V::sub(pz, cz);
  const F D = V::sqrt(V::fma(dx, dx, V::fma(dy, dy, V::mul(dz, dz))));
  const F invD = V::div(one, V::max(D, tiny));
  const F th = V::select(V::lt(r, D), asin01<V>(V::min(V::mul(r, invD), one)), half_pi);
  const auto away = V::lt(zero, D);
  const F ux = V::select(away, V::mul(dx, invD), zero), uy = V::select(away, V::mul(dy, invD), zero);
  const F uz = V::select(away, V::mul(dz, invD), one);
  const I id9 = V::imul(V::iload(id), 9);
  F dl[3];
  for (int i = 0; i < 3; ++i)
    dl[i] = V::fma(V::gather(s.rot + 3 * i, id9), ux,
                   V::fma(V::gather(s.rot + 3 * i + 1, id9), uy, V::mul(V::gather(s.rot + 3 * i + 2, id9), uz)));
  dl[0] = V::select(away, dl[0], zero);  // p at the centre: the rest frame's +z, unturned
  dl[1] = V::select(away, dl[1], zero);
  dl[2] = V::select(away, dl[2], one);
  basis_soa<V>(N, dl[0], dl[1], dl[2], y);
  const int rows = s.weight_rows;
  const F x = V::mul(V::min(th, half_pi), V::set(static_cast<float>((rows - 1) / (sh::kPi / 2))));
  const I row = V::iclamp(V::trunc(x), 0, rows - 2);
  const F fr = V::min(one, V::sub(x, V::to_float(row)));
  const I w0 = V::imul(row, N);
  const I lbase = V::imul(V::iload(id), 3 * N2);
  F acc[3] = {zero, zero, zero};
  for (int l = 0; l < N; ++l) {
    const F a = V::gather(s.weight + l, w0), b = V::gather(s.weight + N + l, w0);
    const F wl = V::mul(V::fma(fr, V::sub(b, a), a), V::set(zh_factor[l]));
    F band[3] = {zero, zero, zero};
    for (int c = l * l; c < (l + 1) * (l + 1); ++c) {
      const F yc = V::load(y + c * W);
      for (int ch = 0; ch < 3; ++ch) band[ch] = V::fma(yc, V::gather(s.L + ch * N2 + c, lbase), band[ch]);
    }
    for (int ch = 0; ch < 3; ++ch) acc[ch] = V::fma(wl, band[ch], acc[ch]);
  }
  alignas(64) float out[3][W];
  for (int ch = 0; ch < 3; ++ch) V::store(out[ch], acc[ch]);
  for (std::size_t l = 0; l < cnt; ++l)
    for (int ch = 0; ch < 3; ++ch) rgb[3 * (j0 + l) + ch] = out[ch][l];
}

template <class V, int N>
void fan_range(const ZhTable& log, ReplacementRule rule, const float* pn, const SphereFan& s, float* g, float* key,
               std::uint8_t* alive, float* rgb) {
  constexpr std::size_t W = V::W;
  // sqrt(4 pi / (2l + 1)): the ZH rotation rule (sh::zh_rotate) of the emission's weight about d.
  static const std::array<float, N> zh_factor = [] {
    std::array<float, N> f{};
    for (int l = 0; l < N; ++l) f[l] = static_cast<float>(sh::zh_rotation_factor(l));
    return f;
  }();
  for (std::size_t j = 0; j < s.count; j += W)
    fan_block<V, N>(log, rule, pn, s, j, s.count - j < W ? s.count - j : W, zh_factor.data(), g, key, alive, rgb);
}

inline void fan_dispatch(int order, const ZhTable& log, ReplacementRule rule, const float* pn, const SphereFan& s, float* g, float* key,
                         std::uint8_t* alive, float* rgb) {
  switch (order) {
    case 3: fan_range<Vec, 3>(log, rule, pn, s, g, key, alive, rgb); return;
    case 4: fan_range<Vec, 4>(log, rule, pn, s, g, key, alive, rgb); return;
    case 5: fan_range<Vec, 5>(log, rule, pn, s, g, key, alive, rgb); return;
    case 6: fan_range<Vec, 6>(log, rule, pn, s, g, key, alive, rgb); return;
    case 7: fan_range<Vec, 7>(log, rule, pn, s, g, key, alive, rgb); return;
    case 8: fan_range<Vec, 8>(log, rule, pn, s, g, key, alive, rgb); return;
    default: break;
  }
}
