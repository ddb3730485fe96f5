// Batched (structure-of-arrays) SH exponentiation and diffuse shading for SHEXP, written once over a
// SIMD wrapper V. Without include guard on purpose: kernel.cpp includes it once per instruction set
// after kernel_body.hpp (see there). Expects in scope: ProductPlan, BatchExp, basis_consts().

// out = f * f (eq. 3 with f = g), f and out [n^2][W] lane-major blocks.
template <class V>
inline void square_soa(const ProductPlan& p, const float* f, float* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  const int n2 = p.order * p.order;
  for (int i = 0; i < n2; ++i) {
    F acc = V::set(0.0f);
    for (int t = p.sq_begin[i]; t < p.sq_begin[i + 1]; ++t)
      acc = V::fma(V::set(p.sq_v[t]), V::mul(V::load(f + p.sq_j[t] * W), V::load(f + p.sq_k[t] * W)), acc);
    V::store(out + i * W, acc);
  }
}

// out = f * g (eq. 3), blocks as above.
template <class V>
inline void product_soa(const ProductPlan& p, const float* f, const float* g, float* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  const int n2 = p.order * p.order;
  for (int i = 0; i < n2; ++i) {
    F acc = V::set(0.0f);
    for (int t = p.pr_begin[i]; t < p.pr_offdiag_end[i]; ++t) {
      const int j = p.pr_j[t] * W, k = p.pr_k[t] * W;
      acc = V::fma(V::set(p.pr_v[t]), V::fma(V::load(f + j), V::load(g + k), V::mul(V::load(f + k), V::load(g + j))), acc);
    }
    for (int t = p.pr_offdiag_end[i]; t < p.pr_begin[i + 1]; ++t) {
      const int j = p.pr_j[t] * W;
      acc = V::fma(V::set(p.pr_v[t]), V::mul(V::load(f + j), V::load(g + j)), acc);
    }
    V::store(out + i * W, acc);
  }
}

// HYB, OL and PS*-p (section 4) for up to W receivers at once, with the rules of sh::exp_hyb,
// sh::exp_ol and sh::exp_ps_star per lane (DC isolation, squaring count from ||f^||, DC factor
// applied before the squarings). Lanes square as many times as the lane with most squarings; each
// lane keeps the result after its own count. f, g receiver-major (n^2 floats per receiver).
template <class V>
void exp_block(const BatchExp& e, const float* f_rm, std::size_t cnt, float* g_rm, std::size_t first, sh::ExpStats& st) {
  using F = typename V::F;
  constexpr int W = V::W;
  const int n = e.order, n2 = n * n;
  const ProductPlan& p = *e.plan;
  alignas(64) float x[sh::kMaxCoeffs * W], g[sh::kMaxCoeffs * W], t0[sh::kMaxCoeffs * W], t1[sh::kMaxCoeffs * W],
      t2[sh::kMaxCoeffs * W], t3[sh::kMaxCoeffs * W];
  alignas(64) float sq[W], dcv[W];
  int s[W];
  int smax = 0;
  for (int l = 0; l < W; ++l) {
    const std::size_t src_lane = static_cast<std::size_t>(l) < cnt ? l : cnt - 1;
    const float* src = f_rm + src_lane * n2;
    double norm2 = 0.0;
    for (int i = 0; i < n2; ++i) {
      if (!std::isfinite(src[i]))
        throw std::invalid_argument("shexp exponentiate: receiver " + std::to_string(first + src_lane) + " has log coefficient " +
                                    std::to_string(i) + " = " + std::to_string(src[i]));
      if (i > 0) norm2 += static_cast<double>(src[i]) * src[i];
    }
    const double norm = std::sqrt(norm2);
    s[l] = e.method == sh::ExpMethod::OL ? 0 : sh::paper_squarings(norm);
    smax = s[l] > smax ? s[l] : smax;
    sq[l] = static_cast<float>(s[l]);
    const double dc = std::exp(static_cast<double>(src[0]) / sh::kSqrt4Pi / std::ldexp(1.0, s[l]));
    if (!(dc <= static_cast<double>(std::numeric_limits<float>::max())))
      throw std::overflow_error("shexp exponentiate: receiver " + std::to_string(first + src_lane) + ": DC coefficient " +
                                std::to_string(src[0]) + " gives a mean log value whose exponential overflows");
    dcv[l] = static_cast<float>(dc);
    const float scale = static_cast<float>(std::ldexp(1.0, -s[l]));
    x[l] = 0.0f;
    for (int i = 1; i < n2; ++i) x[i * W + l] = src[i] * scale;
    if (e.method != sh::ExpMethod::PSStar) {
      double a = 1.0, b = 1.0;
      e.tables->ol_lookup(std::ldexp(norm, -s[l]), a, b);  // eq. 23
      g[l] = static_cast<float>(a * sh::kSqrt4Pi) * dcv[l];
      for (int i = 1; i < n2; ++i) g[i * W + l] = static_cast<float>(b) * x[i * W + l] * dcv[l];
    }
  }
  long long series_squares = 0, series_products = 0;
  if (e.method == sh::ExpMethod::PSStar) {
    // Factored series (eq. 22): even powers x^2 = x*x, x^4 = x^2*x^2, x^6 = x^4*x^2, ...
    float *even = g, *odd = t0, *pw = t1, *x2 = t2, *tmp = t3;
    for (int i = 0; i < n2 * W; ++i) even[i] = odd[i] = 0.0f;
    for (int l = 0; l < W; ++l) even[l] = odd[l] = static_cast<float>(sh::kSqrt4Pi);
    double fact = 1.0;
    for (int k = 2; k <= e.degree; ++k) {
      fact *= k;
      const F h = V::set(static_cast<float>(1.0 / fact));
      if (k % 2 == 0) {
        if (k == 2) {
          square_soa<V>(p, x, x2);
          for (int i = 0; i < n2 * W; ++i) pw[i] = x2[i];
          ++series_squares;
        } else if (k == 4) {
          square_soa<V>(p, x2, tmp);
          for (int i = 0; i < n2 * W; ++i) pw[i] = tmp[i];
          ++series_squares;
        } else {
          product_soa<V>(p, pw, x2, tmp);
          for (int i = 0; i < n2 * W; ++i) pw[i] = tmp[i];
          ++series_products;
        }
        for (int i = 0; i < n2; ++i) V::store(even + i * W, V::fma(h, V::load(pw + i * W), V::load(even + i * W)));
      } else {
        for (int i = 0; i < n2; ++i) V::store(odd + i * W, V::fma(h, V::load(pw + i * W), V::load(odd + i * W)));
      }
    }
    if (e.degree >= 3) {
      product_soa<V>(p, x, odd, tmp);
      ++series_products;
      for (int i = 0; i < n2; ++i) V::store(even + i * W, V::add(V::load(even + i * W), V::load(tmp + i * W)));
    } else {
      for (int i = 0; i < n2; ++i) V::store(even + i * W, V::add(V::load(even + i * W), V::load(x + i * W)));
    }
    const F dc = V::load(dcv);
    for (int i = 0; i < n2; ++i) V::store(g + i * W, V::mul(V::load(g + i * W), dc));
  }
  // Scaling/squaring (eq. 21), each lane its own count.
  const F lane_s = V::load(sq);
  for (int it = 0; it < smax; ++it) {
    square_soa<V>(p, g, t3);
    const auto more = V::lt(V::set(static_cast<float>(it)), lane_s);
    for (int i = 0; i < n2; ++i) V::store(g + i * W, V::select(more, V::load(t3 + i * W), V::load(g + i * W)));
  }
  for (std::size_t l = 0; l < cnt; ++l) {
    float* dst = g_rm + l * n2;
    for (int i = 0; i < n2; ++i) {
      dst[i] = g[i * W + l];
      if (!std::isfinite(dst[i]))
        throw std::overflow_error("shexp exponentiate: receiver " + std::to_string(first + l) + ": result coefficient " +
                                  std::to_string(i) + " overflowed");
    }
    st.squarings += s[l];
    st.squares += s[l] + static_cast<int>(series_squares);
    st.products += static_cast<int>(series_products);
  }
}

inline void exp_dispatch(const BatchExp& e, const float* f_rm, std::size_t count, float* g_rm, std::size_t first, sh::ExpStats& st) {
  constexpr std::size_t W = Vec::W;
  for (std::size_t i = 0; i < count; i += W)
    exp_block<Vec>(e, f_rm + i * e.order * e.order, count - i < W ? count - i : W, g_rm + i * e.order * e.order, first + i, st);
}

// Real SH basis y(s) for W directions at runtime order n (the recurrence of kernel_body.hpp).
template <class V>
inline void basis_soa(int n, typename V::F sx, typename V::F sy, typename V::F sz, float* y) {
  using F = typename V::F;
  constexpr int W = V::W;
  const BasisConsts& bc = basis_consts();
  F C[kMaxAccOrder], S[kMaxAccOrder];
  C[0] = V::set(1.0f);
  S[0] = V::set(0.0f);
  for (int m = 1; m < n; ++m) {
    C[m] = V::fnma(S[m - 1], sy, V::mul(C[m - 1], sx));
    S[m] = V::fma(S[m - 1], sx, V::mul(C[m - 1], sy));
  }
  for (int m = 0; m < n; ++m) {
    F q_prev = V::set(0.0f), q = V::set(bc.qmm[m]);
    for (int l = m; l < n; ++l) {
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
        V::store(y + i0 * W, q);
      } else {
        V::store(y + (i0 + m) * W, V::mul(q, C[m]));
        V::store(y + (i0 - m) * W, V::mul(q, S[m]));
      }
    }
  }
}

// Diffuse shading E/pi = (H(N) * g) . L per colour channel (paper 004 eq. 9 and section 7) for
// receivers [begin, end): H(N) is the clamped cosine turned to N (hcoef_l y_lm(N)), g optionally
// windowed per band; one SH product per receiver serves the three channels.
template <class V>
void shade_block(const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t cnt, glm::vec3* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  const int n = b.order, n2 = n * n;
  alignas(64) float lane[3][W];
  alignas(64) float H[sh::kMaxCoeffs * W], g[sh::kMaxCoeffs * W], HG[sh::kMaxCoeffs * W];
  for (int l = 0; l < W; ++l) {
    const std::size_t i = begin + (static_cast<std::size_t>(l) < cnt ? l : cnt - 1);
    lane[0][l] = rec.nx[i];
    lane[1][l] = rec.ny[i];
    lane[2][l] = rec.nz[i];
    for (int k = 0; k < n2; ++k) g[k * W + l] = b.g ? b.g[i * n2 + k] : (k == 0 ? static_cast<float>(sh::kSqrt4Pi) : 0.0f);
  }
  basis_soa<V>(n, V::load(lane[0]), V::load(lane[1]), V::load(lane[2]), H);
  for (int k = 0; k < n2; ++k) {
    V::store(H + k * W, V::mul(V::load(H + k * W), V::set(b.hcoef[k])));
    V::store(g + k * W, V::mul(V::load(g + k * W), V::set(b.gwin[k])));
  }
  product_soa<V>(*b.plan, H, g, HG);
  F e[3] = {V::set(0.0f), V::set(0.0f), V::set(0.0f)};
  for (int k = 0; k < n2; ++k) {
    const F hg = V::load(HG + k * W);
    for (int c = 0; c < 3; ++c) e[c] = V::fma(hg, V::set(b.L[c * n2 + k]), e[c]);
  }
  for (int c = 0; c < 3; ++c) V::store(lane[c], e[c]);
  for (std::size_t l = 0; l < cnt; ++l) out[l] = glm::vec3(lane[0][l], lane[1][l], lane[2][l]);
}

inline void shade_dispatch(const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out) {
  constexpr std::size_t W = Vec::W;
  for (std::size_t i = begin; i < end; i += W) shade_block<Vec>(b, rec, i, end - i < W ? end - i : W, out + (i - begin));
}
