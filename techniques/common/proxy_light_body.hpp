// Sphere proxies as diffuse secondary lights (paper 000 section 5), written once over a SIMD wrapper
// V. Without include guard on purpose: kernel.cpp includes it once per instruction set after
// kernel_body.hpp and batch_body.hpp (see there). Expects in scope: ProxyLightTables, ProxyLightList,
// ReceiverSoA, blocker_view, basis_soa.

// V::W receivers (lanes[0..5] = px, py, pz, nx, ny, nz; lanes at or past `valid` repeat the last
// receiver and are not counted) against every proxy of `L`. Adds to out[c * W + lane]: c = 0..2 the
// radiance sums, c = 3 omega. Returns the pairs counted.
template <class V, int N>
long long proxy_light_block(const ProxyLightTables& t, const float (*lanes)[V::W], int valid, const ProxyLightList& L,
                            float* out) {
  using F = typename V::F;
  using I = typename V::I;
  using M = typename V::M;
  constexpr int W = V::W;
  alignas(64) static constexpr float kLane[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  static_assert(W <= 16, "lane index table too short");
  F p[6];
  for (int a = 0; a < 6; ++a) p[a] = V::load(lanes[a]);
  const F zero = V::set(0.0f), one = V::set(1.0f);
  const M in_range = V::lt(V::load(kLane), V::set(static_cast<float>(valid)));
  const bool cut = t.eta > 0.0f;
  const bool reach = t.reach > 0.0f;
  const F eta = V::set(t.eta);
  const float inv_pi = static_cast<float>(1.0 / sh::kPi);
  // P_l(t) = a_l t P_{l-1} - b_l P_{l-2} (Bonnet), a_l = (2l - 1)/l, b_l = (l - 1)/l.
  float la[N] = {}, lb[N] = {};
  for (int l = 2; l < N; ++l) {
    la[l] = static_cast<float>(2 * l - 1) / static_cast<float>(l);
    lb[l] = static_cast<float>(l - 1) / static_cast<float>(l);
  }
  F acc_r = zero, acc_g = zero, acc_b = zero, acc_om = zero, acc_pairs = zero;
  alignas(64) float y[N * N * W];  // the basis of the current proxy's direction, lane-major

  for (std::size_t j = 0; j < L.count; ++j) {
    const float cx = L.cx[j], cy = L.cy[j], cz = L.cz[j], rj = L.r[j];
    M act = in_range;
    if (reach) {
      // |c - p| < reach r for the proxy as given, before the rule (the receivers binning gave it).
      const F dx = V::sub(V::set(cx), p[0]), dy = V::sub(V::set(cy), p[1]), dz = V::sub(V::set(cz), p[2]);
      const F d2 = V::fma(dx, dx, V::fma(dy, dy, V::mul(dz, dz)));
      const float rr = t.reach * rj;
      act = V::land(act, V::lt(d2, V::set(rr * rr)));
      if (!V::any(act)) continue;
    }
    // The rule-adjusted sphere (paper 004 section 6.2), its angular radius (eq. 1: sin theta =
    // min(1, r/|c - p|)) and the proxy's own visibility F_l(theta) (eq. 3, clamped if asked).
    F fl[N], sx, sy, sz, u;
    const F st = blocker_view<V, N>(*t.vis, t.rule, p, cx, cy, cz, rj, fl, sx, sy, sz, &u);
    act = V::land(act, V::lt(zero, st));
    // Outside the sphere of influence (section 4.1): |c - p| >= eta r, i.e. sin theta <= 1/eta.
    if (cut) act = V::land(act, V::lt(one, V::mul(st, eta)));
    if (!V::any(act)) continue;

    // V . H(N) = sum_l F_l vh_l P_l(s . N) (addition theorem).
    const F ct = V::min(V::max(V::fma(sx, p[3], V::fma(sy, p[4], V::mul(sz, p[5]))), V::set(-1.0f)), one);
    F pm2 = one, pm1 = ct;
    F vdoth = V::mul(fl[0], V::set(t.vh[0]));
    if (N > 1) vdoth = V::fma(V::mul(fl[1], V::set(t.vh[1])), ct, vdoth);
#pragma GCC unroll 16
    for (int l = 2; l < N; ++l) {
      const F pl = V::fnma(V::set(lb[l]), pm2, V::mul(V::set(la[l]), V::mul(ct, pm1)));
      vdoth = V::fma(V::mul(fl[l], V::set(t.vh[l])), pl, vdoth);
      pm2 = pm1;
      pm1 = pl;
    }

    // Band factors: (-1)^l for eq. 13 (L~(-s) = sum (-1)^l y_lm(s) L~_lm), sqrt(4pi/(2l+1)) D_l(theta)
    // for eq. 15, on the visibility table's rows.
    F fac[N];
    if (t.band_factor) {
      const I k = V::iclamp(V::trunc(u), 0, t.band_factor->rows - 2);
      V::template fetch_bands<N>(*t.band_factor, k, V::sub(u, V::to_float(k)), fac);
    } else {
#pragma GCC unroll 16
      for (int l = 0; l < N; ++l) fac[l] = V::set((l & 1) ? -1.0f : 1.0f);
    }

    // kappa_c = sum_l fac_l sum_m y_lm(s) L~_lm,c, y by the shared recurrence (basis_soa).
    basis_soa<V>(N, sx, sy, sz, y);
    F band[N][3];
    const float* lt = t.ltilde;
#pragma GCC unroll 16
    for (int l = 0; l < N; ++l) {
      band[l][0] = band[l][1] = band[l][2] = zero;
      for (int i = l * l; i < (l + 1) * (l + 1); ++i) {
        const F yi = V::load(y + i * W);
        for (int c = 0; c < 3; ++c) band[l][c] = V::fma(yi, V::set(lt[3 * i + c]), band[l][c]);
      }
    }
    F kap[3] = {zero, zero, zero};
#pragma GCC unroll 16
    for (int l = 0; l < N; ++l)
      for (int c = 0; c < 3; ++c) kap[c] = V::fma(fac[l], band[l][c], kap[c]);

    // Diffuse proxy: leaving radiance albedo / pi L~.
    const glm::vec3& a = L.albedo[j];
    const F w = V::select(act, vdoth, zero);
    acc_r = V::fma(V::mul(V::set(a.x * inv_pi), kap[0]), w, acc_r);
    acc_g = V::fma(V::mul(V::set(a.y * inv_pi), kap[1]), w, acc_g);
    acc_b = V::fma(V::mul(V::set(a.z * inv_pi), kap[2]), w, acc_b);
    acc_om = V::add(acc_om, V::select(act, fl[0], zero));  // omega = F_0 (eq. 2 through the DC term)
    acc_pairs = V::add(acc_pairs, V::select(act, one, zero));
  }
  V::store(out + 0 * W, V::add(V::load(out + 0 * W), acc_r));
  V::store(out + 1 * W, V::add(V::load(out + 1 * W), acc_g));
  V::store(out + 2 * W, V::add(V::load(out + 2 * W), acc_b));
  V::store(out + 3 * W, V::add(V::load(out + 3 * W), acc_om));
  alignas(64) float pc[W];
  V::store(pc, acc_pairs);
  long long pairs = 0;
  for (int k = 0; k < W; ++k) pairs += static_cast<long long>(pc[k]);  // exact: at most 2^24 per lane
  return pairs;
}

template <class V, int N>
long long proxy_light_range(const ProxyLightTables& t, const ReceiverSoA& rec, std::size_t begin, std::size_t end,
                            const ProxyLightList& L, float* rgb, float* omega) {
  constexpr int W = V::W;
  alignas(64) float lanes[6][W];
  alignas(64) float res[4 * W];
  long long pairs = 0;
  for (std::size_t i0 = begin; i0 < end; i0 += W) {
    const std::size_t cnt = end - i0 < static_cast<std::size_t>(W) ? end - i0 : static_cast<std::size_t>(W);
    receiver_lanes<W>(rec, i0, cnt, lanes);
    for (float& v : res) v = 0.0f;
    pairs += proxy_light_block<V, N>(t, lanes, static_cast<int>(cnt), L, res);
    for (std::size_t k = 0; k < cnt; ++k) {
      for (int c = 0; c < 3; ++c) rgb[3 * (i0 + k) + c] += res[c * W + k];
      omega[i0 + k] += res[3 * W + k];
    }
  }
  return pairs;
}

inline long long proxy_light_dispatch(int order, const ProxyLightTables& t, const ReceiverSoA& rec, std::size_t begin,
                                      std::size_t end, const ProxyLightList& L, float* rgb, float* omega) {
  switch (order) {
    case 3: return proxy_light_range<Vec, 3>(t, rec, begin, end, L, rgb, omega);
    case 4: return proxy_light_range<Vec, 4>(t, rec, begin, end, L, rgb, omega);
    case 5: return proxy_light_range<Vec, 5>(t, rec, begin, end, L, rgb, omega);
    case 6: return proxy_light_range<Vec, 6>(t, rec, begin, end, L, rgb, omega);
    default: return -1;
  }
}
