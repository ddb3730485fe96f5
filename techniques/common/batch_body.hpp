// Batched (structure-of-arrays) SH exponentiation and diffuse shading for SHEXP, written once over a
// SIMD wrapper V. Without include guard on purpose: kernel.cpp includes it once per instruction set
// after kernel_body.hpp (see there). Expects in scope: ProductPlan, BatchExp, basis_consts().

// square_fixed_<n>, product_fixed_<n> and their dispatch by order: the plan's terms written out
// (generated at build time by gen/sh_plan_cpp.cpp, in this namespace for each instruction set).
#include "sh_plan_unrolled.hpp"

// out = f * f (eq. 3 with f = g), f and out [n^2][W] lane-major blocks. The orders written out go
// through square_fixed: the same terms in the same order of operations as the loop below (the plan
// is ProductPlan::get's, the only one there is), so the same floats, without the loop's index work.
template <class V>
inline void square_soa(const ProductPlan& p, const float* f, float* out) {
  if (square_fixed<V>(p.order, f, out)) return;
  using F = typename V::F;
  constexpr int W = V::W;
  const int n2 = p.order * p.order;
  // Four partial sums per output: a single one would chain every term on the multiply-add latency.
  for (int i = 0; i < n2; ++i) {
    F acc[4] = {V::set(0.0f), V::set(0.0f), V::set(0.0f), V::set(0.0f)};
    const int b = p.sq_begin[i], e = p.sq_begin[i + 1];
    int t = b;
    for (; t + 4 <= e; t += 4)
      for (int u = 0; u < 4; ++u)
        acc[u] = V::fma(V::set(p.sq_v[t + u]), V::mul(V::load(f + p.sq_j[t + u] * W), V::load(f + p.sq_k[t + u] * W)), acc[u]);
    for (; t < e; ++t) acc[0] = V::fma(V::set(p.sq_v[t]), V::mul(V::load(f + p.sq_j[t] * W), V::load(f + p.sq_k[t] * W)), acc[0]);
    V::store(out + i * W, V::add(V::add(acc[0], acc[1]), V::add(acc[2], acc[3])));
  }
}

// out = f * g (eq. 3), blocks as above; written out where the order is (product_fixed), as squares.
template <class V>
inline void product_soa(const ProductPlan& p, const float* f, const float* g, float* out) {
  if (product_fixed<V>(p.order, f, g, out)) return;
  using F = typename V::F;
  constexpr int W = V::W;
  const int n2 = p.order * p.order;
  for (int i = 0; i < n2; ++i) {
    F acc[4] = {V::set(0.0f), V::set(0.0f), V::set(0.0f), V::set(0.0f)};  // see square_soa
    const int b = p.pr_begin[i], m = p.pr_offdiag_end[i], e = p.pr_begin[i + 1];
    auto off = [&](int t, F a) {
      const int j = p.pr_j[t] * W, k = p.pr_k[t] * W;
      return V::fma(V::set(p.pr_v[t]), V::fma(V::load(f + j), V::load(g + k), V::mul(V::load(f + k), V::load(g + j))), a);
    };
    auto diag = [&](int t, F a) {
      const int j = p.pr_j[t] * W;
      return V::fma(V::set(p.pr_v[t]), V::mul(V::load(f + j), V::load(g + j)), a);
    };
    int t = b;
    for (; t + 4 <= m; t += 4)
      for (int u = 0; u < 4; ++u) acc[u] = off(t + u, acc[u]);
    for (; t < m; ++t) acc[0] = off(t, acc[0]);
    for (; t + 4 <= e; t += 4)
      for (int u = 0; u < 4; ++u) acc[u] = diag(t + u, acc[u]);
    for (; t < e; ++t) acc[1] = diag(t, acc[1]);
    V::store(out + i * W, V::add(V::add(acc[0], acc[1]), V::add(acc[2], acc[3])));
  }
}

// Up to W vectors of n2 floats (receiver-major from src; lanes past cnt repeat the last) into
// [P][W] lane-major dst, P = n2 rounded up to W (the rows past n2 zero), through W x W transposes;
// `rows` is scratch of P W floats.
template <class V>
inline void lanes_in(const float* src, std::size_t cnt, int n2, float* rows, float* dst) {
  constexpr int W = V::W;
  const int P = (n2 + W - 1) / W * W;
  for (int l = 0; l < W; ++l) {
    const std::size_t r = static_cast<std::size_t>(l) < cnt ? l : cnt - 1;
    std::memcpy(rows + l * P, src + r * n2, sizeof(float) * n2);
    for (int i = n2; i < P; ++i) rows[l * P + i] = 0.0f;
  }
  for (int k0 = 0; k0 < P; k0 += W) V::transpose(rows + k0, P, dst + k0 * W);
}

// The reverse: lanes [0, cnt) of [P][W] src (its rows past n2 zeroed here) to receiver-major dst.
template <class V>
inline void lanes_out(float* src, std::size_t cnt, int n2, float* rows, float* dst) {
  constexpr int W = V::W;
  const int P = (n2 + W - 1) / W * W;
  for (int i = n2 * W; i < P * W; ++i) src[i] = 0.0f;
  for (int k0 = 0; k0 < P; k0 += W) {
    V::transpose(src + k0 * W, W, rows);
    const int m = n2 - k0 < W ? n2 - k0 : W;
    for (std::size_t l = 0; l < cnt; ++l) std::memcpy(dst + l * n2 + k0, rows + l * W, sizeof(float) * m);
  }
}

// 2^k as a double for |k| < 1023: std::ldexp(1.0, k) without its call (the squaring counts of
// sh::paper_squarings stay far inside that range for float log vectors).
inline double pow2(int k) { return std::bit_cast<double>(static_cast<std::uint64_t>(1023 + k) << 52); }

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
  alignas(64) float sq[W], dcv[W], scv[W], av[W], bv[W];
  int s[W];
  int smax = 0;
  // The input transposed to coefficient-major through W x W blocks (lanes_in), its
  // finite check and ||f^||^2 in double, each lane summing its squares in the order sh::exp does
  // (float products are exact in double, so the sums are sh::exp's bit for bit); then the scalar
  // decisions of the method per lane; the per-coefficient scaling runs vectorised below.
  static_assert(sh::kMaxCoeffs % W == 0, "the padded rows and their transposes fit the coefficient buffers");
  alignas(64) float rows[sh::kMaxCoeffs * W];
  lanes_in<V>(f_rm, cnt, n2, rows, x);
  alignas(64) float finite[W];
  alignas(64) double norm2v[W];
  {
    F check = V::set(0.0f);  // NaN in a lane where a coefficient is NaN or infinite
    for (int i = 0; i < n2; ++i) check = V::add(check, V::mul(V::load(x + i * W), V::set(0.0f)));
    V::store(finite, check);
    V::sum_squares_double(x, 1, n2, norm2v);
  }
  for (int l = 0; l < W; ++l) {
    const std::size_t src_lane = static_cast<std::size_t>(l) < cnt ? l : cnt - 1;
    const float* src = f_rm + src_lane * n2;
    if (!(finite[l] == 0.0f))
      for (int i = 0; i < n2; ++i)
        if (!std::isfinite(src[i]))
          throw std::invalid_argument("exponentiate: receiver " + std::to_string(first + src_lane) + " has log coefficient " +
                                      std::to_string(i) + " = " + std::to_string(src[i]));
    const double norm2 = norm2v[l];
    const double norm = std::sqrt(norm2);
    s[l] = e.method == sh::ExpMethod::OL || e.method == sh::ExpMethod::PS ? 0 : sh::paper_squarings(norm);
    smax = s[l] > smax ? s[l] : smax;
    sq[l] = static_cast<float>(s[l]);
    const double dc = std::exp(static_cast<double>(src[0]) / sh::kSqrt4Pi / pow2(s[l]));
    if (!(dc <= static_cast<double>(std::numeric_limits<float>::max())))
      throw std::overflow_error("exponentiate: receiver " + std::to_string(first + src_lane) + ": DC coefficient " +
                                std::to_string(src[0]) + " gives a mean log value whose exponential overflows");
    dcv[l] = static_cast<float>(dc);
    scv[l] = static_cast<float>(pow2(-s[l]));
    if (e.method == sh::ExpMethod::HYB || e.method == sh::ExpMethod::OL) {
      double a = 1.0, b = 1.0;
      e.tables->ol_lookup(norm * pow2(-s[l]), a, b);  // eq. 23
      av[l] = static_cast<float>(a * sh::kSqrt4Pi) * dcv[l];
      bv[l] = static_cast<float>(b);
    }
  }
  // x = f^ / 2^s (eqs. 19, 21); OL/HYB: g = a 1 + b x, times the DC factor (eq. 23).
  {
    const F scale = V::load(scv), dc = V::load(dcv), bb = V::load(bv);
    V::store(x, V::set(0.0f));
    for (int i = 1; i < n2; ++i) V::store(x + i * W, V::mul(V::load(x + i * W), scale));
    if (e.method == sh::ExpMethod::HYB || e.method == sh::ExpMethod::OL) {
      V::store(g, V::load(av));
      for (int i = 1; i < n2; ++i) V::store(g + i * W, V::mul(V::mul(bb, V::load(x + i * W)), dc));
    }
  }
  long long series_squares = 0, series_products = 0;
  if (e.method == sh::ExpMethod::PS) {
    // Plain product series (eq. 17) on the whole f (no DC isolation, no scaling), powers
    // accumulated left to right: term_k = term_{k-1} * f / k. Subnormal terms are flushed to zero by
    // the FTZ mode kernel.cpp sets (sh::exp_ps flushes them explicitly).
    for (int l = 0; l < W; ++l) x[l] = f_rm[(static_cast<std::size_t>(l) < cnt ? l : cnt - 1) * n2];
    float *term = t0, *next = t1;
    for (int i = 0; i < n2 * W; ++i) term[i] = x[i];
    for (int i = 0; i < n2; ++i) V::store(g + i * W, V::add(V::set(i == 0 ? static_cast<float>(sh::kSqrt4Pi) : 0.0f), V::load(x + i * W)));
    for (int k = 2; k <= e.degree; ++k) {
      product_soa<V>(p, term, x, next);
      ++series_products;
      const F inv = V::set(1.0f / static_cast<float>(k));
      for (int i = 0; i < n2; ++i) {
        const F tk = V::mul(V::load(next + i * W), inv);
        V::store(term + i * W, tk);
        V::store(g + i * W, V::add(V::load(g + i * W), tk));
      }
    }
  } else if (e.method == sh::ExpMethod::PSStar) {
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
  // Back to receiver-major through W x W blocks, after the same finite check in lanes.
  {
    F check = V::set(0.0f);
    for (int i = 0; i < n2; ++i) check = V::add(check, V::mul(V::load(g + i * W), V::set(0.0f)));
    V::store(finite, check);
    for (std::size_t l = 0; l < cnt; ++l)
      if (!(finite[l] == 0.0f))
        for (int i = 0; i < n2; ++i)
          if (!std::isfinite(g[i * W + l]))
            throw std::overflow_error("exponentiate: receiver " + std::to_string(first + l) + ": result coefficient " +
                                      std::to_string(i) + " overflowed");
    lanes_out<V>(g, cnt, n2, rows, g_rm);
  }
  for (std::size_t l = 0; l < cnt; ++l) {
    st.squarings += s[l];
    st.squares += s[l] + static_cast<int>(series_squares);
    st.products += static_cast<int>(series_products);
  }
}

// square_batch and product_batch (g null: squares): W vectors at a time into the lanes and back.
inline void product_dispatch(const ProductPlan& p, const float* f, const float* g, float* out, std::size_t count) {
  constexpr int W = Vec::W;
  const int n2 = p.order * p.order;
  alignas(64) float rows[sh::kMaxCoeffs * W], a[sh::kMaxCoeffs * W], b[sh::kMaxCoeffs * W], o[sh::kMaxCoeffs * W];
  for (std::size_t i = 0; i < count; i += W) {
    const std::size_t cnt = count - i < static_cast<std::size_t>(W) ? count - i : W;
    lanes_in<Vec>(f + i * n2, cnt, n2, rows, a);
    if (g) {
      lanes_in<Vec>(g + i * n2, cnt, n2, rows, b);
      product_soa<Vec>(p, a, b, o);
    } else {
      square_soa<Vec>(p, a, o);
    }
    lanes_out<Vec>(o, cnt, n2, rows, out + i * n2);
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

// Paper 000 eq. 11 for receiver i: row = sum_t w_t coarse[idx_t], `stride` floats per coarse sample,
// W floats at a time summed in a register over the taps (a sum kept in memory would chain every
// tap's load to the last one's store), the rest one at a time. False (row untouched) where the
// receiver's pixel has no tap.
template <class V>
inline bool interpolate_taps(const BatchShade::Taps& tp, std::size_t i, int stride, float* row) {
  using F = typename V::F;
  constexpr int W = V::W;
  const std::int32_t pixel = tp.pixel[i];
  const std::array<std::int32_t, 4>& idx = tp.index[pixel];
  if (idx[0] < 0) return false;
  const std::array<float, 4>& wt = tp.weight[pixel];
  const float* src[4];
  int taps = 0;
  for (; taps < 4 && idx[taps] >= 0; ++taps) src[taps] = tp.coarse + static_cast<std::size_t>(idx[taps]) * stride;
  int k = 0;
  for (; k + W <= stride; k += W) {
    F acc = V::mul(V::set(wt[0]), V::load(src[0] + k));
    for (int t = 1; t < taps; ++t) acc = V::fma(V::set(wt[t]), V::load(src[t] + k), acc);
    V::store(row + k, acc);
  }
  for (; k < stride; ++k) {
    float acc = wt[0] * src[0][k];
    for (int t = 1; t < taps; ++t) acc += wt[t] * src[t][k];
    row[k] = acc;
  }
  return true;
}

// Diffuse shading E/pi = (H(N) * g) . L per colour channel (paper 004 eq. 9 and section 7) for
// receivers [begin, end): H(N) is the clamped cosine turned to N (hcoef_l y_lm(N)), g optionally
// windowed per band; one SH product per receiver serves the three channels.
template <class V>
void shade_block(const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t cnt, glm::vec3* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  const int n = b.order, n2 = n * n;
  constexpr int kMaxRow = (sh::kMaxCoeffs + W - 1) / W * W;
  const int n2p = (n2 + W - 1) / W * W;
  alignas(64) float lane[3][W];
  alignas(64) float H[sh::kMaxCoeffs * W], g[kMaxRow * W], HG[sh::kMaxCoeffs * W], rows[W * kMaxRow];
  for (int l = 0; l < W; ++l) {
    const std::size_t i = begin + (static_cast<std::size_t>(l) < cnt ? l : cnt - 1);
    lane[0][l] = rec.nx[i];
    lane[1][l] = rec.ny[i];
    lane[2][l] = rec.nz[i];
    // The receiver's vector: interpolated from the eq. 11 taps, g_i, or the unshadowed vector (a
    // pixel without a tap, or no g given).
    float* row = rows + l * n2p;
    const bool tapped = b.taps && interpolate_taps<V>(*b.taps, i, n2, row);
    if (!tapped && b.g && !b.taps) {
      std::copy(b.g + i * n2, b.g + (i + 1) * n2, row);
    } else if (!tapped) {
      row[0] = static_cast<float>(sh::kSqrt4Pi);
      std::fill(row + 1, row + n2, 0.0f);
    }
    std::fill(row + n2, row + n2p, 0.0f);
    if (b.taps && b.taps->out) std::copy(row, row + n2, b.taps->out + i * n2);
  }
  // Into the lanes W x W at a time (a copy one float at a time was most of the kernel's time).
  for (int j = 0; j < n2p; j += W) V::transpose(rows + j, static_cast<std::size_t>(n2p), g + j * W);
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

// The same shading through ShadeTransfer: receiver i's row sum_t w_t R_t (3 n^2 floats) from the
// eq. 11 taps, or the unshadowed row where it has none, then out = y(N_i) . row per channel. The
// rows are summed W floats at a time per receiver and turned into lanes W x W at a time.
template <class V>
void shade_transfer_block(const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t cnt, glm::vec3* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  constexpr int kMaxRow = (4 * sh::kMaxCoeffs + W - 1) / W * W;
  const int n = b.order, n2 = n * n, m = b.transfer->stride(), mp = (m + W - 1) / W * W, mr = (3 * n2 + W - 1) / W * W;
  const BatchShade::Taps& tp = *b.taps;
  alignas(64) float lane[3][W];
  alignas(64) float Y[sh::kMaxCoeffs * W], rows[W * kMaxRow], T[kMaxRow * W];
  for (int l = 0; l < W; ++l) {
    const std::size_t i = begin + (static_cast<std::size_t>(l) < cnt ? l : cnt - 1);
    lane[0][l] = rec.nx[i];
    lane[1][l] = rec.ny[i];
    lane[2][l] = rec.nz[i];
    float* row = rows + l * mp;
    if (!interpolate_taps<V>(tp, i, m, row)) std::copy(b.transfer->unshadowed.begin(), b.transfer->unshadowed.end(), row);
    std::fill(row + m, row + mp, 0.0f);
    if (tp.out) std::copy(row + 3 * n2, row + 4 * n2, tp.out + i * n2);  // rows that carry g_i
  }
  // The R part into the lanes (the carried g_i, if any, is read per receiver).
  for (int j = 0; j < mr; j += W) V::transpose(rows + j, static_cast<std::size_t>(mp), T + j * W);
  basis_soa<V>(n, V::load(lane[0]), V::load(lane[1]), V::load(lane[2]), Y);
  for (int c = 0; c < 3; ++c) {
    // Two partial sums: one would chain every coefficient on the multiply-add latency.
    const float* Tc = T + c * n2 * W;
    F e0 = V::set(0.0f), e1 = V::set(0.0f);
    int a = 0;
    for (; a + 2 <= n2; a += 2) {
      e0 = V::fma(V::load(Y + a * W), V::load(Tc + a * W), e0);
      e1 = V::fma(V::load(Y + (a + 1) * W), V::load(Tc + (a + 1) * W), e1);
    }
    if (a < n2) e0 = V::fma(V::load(Y + a * W), V::load(Tc + a * W), e0);
    V::store(lane[c], V::add(e0, e1));
  }
  for (std::size_t l = 0; l < cnt; ++l) out[l] = glm::vec3(lane[0][l], lane[1][l], lane[2][l]);
}

inline void shade_dispatch(const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out) {
  constexpr std::size_t W = Vec::W;
  if (b.transfer) {
    for (std::size_t i = begin; i < end; i += W) shade_transfer_block<Vec>(b, rec, i, end - i < W ? end - i : W, out + (i - begin));
    return;
  }
  for (std::size_t i = begin; i < end; i += W) shade_block<Vec>(b, rec, i, end - i < W ? end - i : W, out + (i - begin));
}

// sin and cos of a in [0, pi/2] by their Taylor polynomials to degree 13 and 14 (truncation below
// 6e-9 on that range): shaders/include/accum_math.glsl's accum_sincos_quarter.
template <class V>
inline void sincos_quarter(typename V::F a, typename V::F& s, typename V::F& c) {
  using F = typename V::F;
  const F a2 = V::mul(a, a);
  F ps = V::set(static_cast<float>(1.0 / 6227020800.0));
  for (const double k : {-1.0 / 39916800.0, 1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0, 1.0})
    ps = V::fma(ps, a2, V::set(static_cast<float>(k)));
  s = V::mul(a, ps);
  F pc = V::set(static_cast<float>(-1.0 / 87178291200.0));
  for (const double k : {1.0 / 479001600.0, -1.0 / 3628800.0, 1.0 / 40320.0, -1.0 / 720.0, 1.0 / 24.0, -0.5, 1.0})
    pc = V::fma(pc, a2, V::set(static_cast<float>(k)));
  c = pc;
}

// LightLobeTable::lookup_unit's coordinate of x in [0, range] over `rows` samples, in lanes: the
// cell's first row (as a float) and the weight of the next, the last cell interpolating to its end.
template <class V>
inline void table_coord(typename V::F x, float range, int rows, typename V::F& k0, typename V::F& w) {
  using F = typename V::F;
  const F last = V::set(static_cast<float>(rows - 1));
  F u = V::mul(V::div(x, V::set(range)), last);
  u = V::select(V::lt(V::set(0.0f), u), u, V::set(0.0f));  // NaN and negatives to 0, as !(u > 0)
  u = V::min(u, last);
  k0 = V::min(V::to_float(V::trunc(u)), V::set(static_cast<float>(rows - 2)));
  w = V::sub(u, k0);
}

// Paper 004 section 7's spherical lights for up to W receivers: lights_batch's block. Per light and
// lane the steps of light_lh_world (angular radius, angle to the normal, the table's lobe, its axis
// turned into the receiver's frame) with shade.comp's polynomials for asin, acos, sin and cos and the
// table's bilinear lookup gathered.
template <class V>
void lights_block(const LightLobeTable& t, const std::vector<scene::SphericalLight>& lights, const float* gwin,
                  const ReceiverSoA& rec, std::size_t begin, std::size_t cnt, const float* g, glm::vec3* out) {
  using F = typename V::F;
  constexpr int W = V::W;
  constexpr int kMaxRow = (sh::kMaxCoeffs + W - 1) / W * W;
  const int n = t.order, n2 = n * n, n2p = (n2 + W - 1) / W * W;
  const float half_pi = static_cast<float>(sh::kPi / 2), pi = static_cast<float>(sh::kPi);
  alignas(64) float lane[6][W], e[3][W];
  alignas(64) float rows[W * kMaxRow], GW[kMaxRow * W], Y[sh::kMaxCoeffs * W];
  for (int l = 0; l < W; ++l) {
    const std::size_t i = begin + (static_cast<std::size_t>(l) < cnt ? l : cnt - 1);
    const float* src[6] = {rec.px.data(), rec.py.data(), rec.pz.data(), rec.nx.data(), rec.ny.data(), rec.nz.data()};
    for (int a = 0; a < 6; ++a) lane[a][l] = src[a][i];
    float* row = rows + l * n2p;
    for (int k = 0; k < n2; ++k) row[k] = (g ? g[i * n2 + k] : (k == 0 ? static_cast<float>(sh::kSqrt4Pi) : 0.0f)) * gwin[k];
    std::fill(row + n2, row + n2p, 0.0f);
  }
  for (int j = 0; j < n2p; j += W) V::transpose(rows + j, static_cast<std::size_t>(n2p), GW + j * W);
  const F px = V::load(lane[0]), py = V::load(lane[1]), pz = V::load(lane[2]);
  const F nx = V::load(lane[3]), ny = V::load(lane[4]), nz = V::load(lane[5]);
  const F zero = V::set(0.0f), one = V::set(1.0f), tiny = V::set(1e-30f);
  const auto vabs = [&](F x) { return V::max(x, V::sub(zero, x)); };
  F acc[3] = {zero, zero, zero};
  for (const scene::SphericalLight& light : lights) {
    if (!(light.radius > 0.0f)) continue;  // light_lh_world: degenerate, no term
    const F R = V::set(light.radius);
    const F dx = V::sub(V::set(light.position.x), px), dy = V::sub(V::set(light.position.y), py),
            dz = V::sub(V::set(light.position.z), pz);
    const F dist = V::sqrt(V::fma(dx, dx, V::fma(dy, dy, V::mul(dz, dz))));
    const auto valid = V::lt(zero, dist);  // a receiver at the light's centre gets no term
    const F sd = V::max(dist, tiny);
    const F ux = V::div(dx, sd), uy = V::div(dy, sd), uz = V::div(dz, sd);
    const F theta = V::select(V::lt(R, dist), asin01<V>(V::min(V::div(R, sd), one)), V::set(half_pi));
    const F cf = V::min(V::max(V::fma(ux, nx, V::fma(uy, ny, V::mul(uz, nz))), V::set(-1.0f)), one);
    const F a = asin01<V>(V::min(vabs(cf), one));
    const F f = V::select(V::ge(cf, zero), V::sub(V::set(half_pi), a), V::add(V::set(half_pi), a));
    // LightLobeTable::lookup_unit in lanes: the bilinear cell of (theta, f) and its four corners'
    // psi and k_l gathered (cell indices below 2^24, exact in float).
    F wi, wj, ci, cj;
    table_coord<V>(theta, half_pi, t.rows_theta, ci, wi);
    table_coord<V>(f, pi, t.rows_f, cj, wj);
    const F rf = V::set(static_cast<float>(t.rows_f));
    const F c00 = V::fma(ci, rf, cj), c10 = V::add(c00, rf);
    const F cell[4] = {c00, V::add(c00, one), c10, V::add(c10, one)};
    const F wq[4] = {V::mul(V::sub(one, wi), V::sub(one, wj)), V::mul(V::sub(one, wi), wj), V::mul(wi, V::sub(one, wj)), V::mul(wi, wj)};
    F psi_v = zero, kv[kMaxAccOrder];
    for (int b = 0; b < n; ++b) kv[b] = zero;
    const F order_f = V::set(static_cast<float>(n));
    for (int q = 0; q < 4; ++q) {
      psi_v = V::fma(wq[q], V::gather(t.psi.data(), V::trunc(cell[q])), psi_v);
      const F kbase = V::mul(cell[q], order_f);
      for (int b = 0; b < n; ++b)
        kv[b] = V::fma(wq[q], V::gather(t.k.data(), V::trunc(V::add(kbase, V::set(static_cast<float>(b))))), kv[b]);
    }
    // k is stored per unit solid angle of the light: times 4 pi sin^2(theta / 2).
    F sh2, ch2;
    sincos_quarter<V>(V::mul(V::set(0.5f), V::max(theta, V::set(static_cast<float>(kLightThetaFloor)))), sh2, ch2);
    const F omega = V::mul(V::set(static_cast<float>(4.0 * sh::kPi)), V::mul(sh2, sh2));
    // Canonical frame: N = z, light in the xz plane on the +x side; the lobe axis at psi from z.
    F tx = V::fnma(cf, nx, ux), ty = V::fnma(cf, ny, uy), tz = V::fnma(cf, nz, uz);
    const F tl = V::sqrt(V::fma(tx, tx, V::fma(ty, ty, V::mul(tz, tz))));
    const auto along = V::ge(V::set(1e-6f), tl);
    const F itl = V::div(one, V::max(tl, tiny));
    // Light on the normal: the lobe is on the normal too (psi = 0 or pi), any tangent will do:
    // N x (1, 0, 0) = (0, Nz, -Ny) where |Nx| < 0.9, else N x (0, 1, 0) = (-Nz, 0, Nx).
    const auto use_x = V::lt(vabs(nx), V::set(0.9f));
    const F fx = V::select(use_x, zero, V::sub(zero, nz)), fy = V::select(use_x, nz, zero), fz = V::select(use_x, V::sub(zero, ny), nx);
    const F ifl = V::div(one, V::max(V::sqrt(V::fma(fx, fx, V::fma(fy, fy, V::mul(fz, fz)))), tiny));
    tx = V::select(along, V::mul(fx, ifl), V::mul(tx, itl));
    ty = V::select(along, V::mul(fy, ifl), V::mul(ty, itl));
    tz = V::select(along, V::mul(fz, ifl), V::mul(tz, itl));
    // (sin psi, cos psi) for psi in [0, pi], reflected about pi/2 (accum_sincos_half).
    const auto low = V::ge(V::set(half_pi), psi_v);
    const F r = V::min(V::max(V::select(low, psi_v, V::sub(V::set(pi), psi_v)), zero), V::set(half_pi));
    F sp, cp;
    sincos_quarter<V>(r, sp, cp);
    cp = V::select(low, cp, V::sub(zero, cp));
    basis_soa<V>(n, V::fma(cp, nx, V::mul(sp, tx)), V::fma(cp, ny, V::mul(sp, ty)), V::fma(cp, nz, V::mul(sp, tz)), Y);
    // (k_l Omega y_lm(axis)) . (gwin g) per band.
    F d = zero;
    for (int b = 0; b < n; ++b) {
      F band = zero;
      for (int m = b * b; m < (b + 1) * (b + 1); ++m) band = V::fma(V::load(Y + m * W), V::load(GW + m * W), band);
      d = V::fma(V::mul(kv[b], omega), band, d);
    }
    d = V::select(valid, d, zero);
    acc[0] = V::fma(d, V::set(light.radiance.x), acc[0]);
    acc[1] = V::fma(d, V::set(light.radiance.y), acc[1]);
    acc[2] = V::fma(d, V::set(light.radiance.z), acc[2]);
  }
  for (int c = 0; c < 3; ++c) V::store(e[c], acc[c]);
  for (std::size_t l = 0; l < cnt; ++l) out[l] += glm::vec3(e[0][l], e[1][l], e[2][l]);
}

inline void lights_dispatch(const LightLobeTable& t, const std::vector<scene::SphericalLight>& lights, const float* gwin,
                            const ReceiverSoA& rec, std::size_t begin, std::size_t end, const float* g, glm::vec3* out) {
  constexpr std::size_t W = Vec::W;
  for (std::size_t i = begin; i < end; i += W) lights_block<Vec>(t, lights, gwin, rec, i, end - i < W ? end - i : W, g, out + (i - begin));
}

// ShadeTransfer's rows: r[s] = sum_b g[s]_b at[b], W floats of the row at a time.
inline void transfer_rows_dispatch(const ShadeTransfer& t, const float* g, std::size_t count, float* r) {
  using V = Vec;
  using F = typename V::F;
  constexpr int W = V::W;
  const int n2 = t.order * t.order, m = 3 * n2, stride = t.stride();
  const float* at = t.at.data();
  for (std::size_t s = 0; s < count; ++s) {
    const float* gs = g + s * n2;
    float* rs = r + s * stride;
    bool zero = true;
    for (int b = 0; b < n2; ++b) zero &= gs[b] == 0.0f;
    if (zero) {
      std::fill(rs, rs + stride, 0.0f);
      continue;
    }
    if (t.carries_visibility) std::copy(gs, gs + n2, rs + m);
    int j = 0;
    for (; j + W <= m; j += W) {
      F acc = V::mul(V::set(gs[0]), V::load(at + j));
      for (int b = 1; b < n2; ++b) acc = V::fma(V::set(gs[b]), V::load(at + b * m + j), acc);
      V::store(rs + j, acc);
    }
    for (; j < m; ++j) {
      float acc = gs[0] * at[j];
      for (int b = 1; b < n2; ++b) acc += gs[b] * at[b * m + j];
      rs[j] = acc;
    }
  }
}

// Product-space accumulation (eq. 6) for V::W receivers at once: acc = 1, then acc = acc * g[i] for
// every blocker in list order, g[i] the cap visibility of the rule-adjusted sphere (eq. 34 with the
// visibility table). A blocker eliminated on every lane is skipped; on some lanes only, those lanes
// multiply by the constant 1. Returns the products done per receiver, summed over the lanes.
template <class V, int N>
long long product_block(const ZhTable& vis, ReplacementRule rule, const float (*lanes)[V::W], std::size_t cnt, const BlockerList& b,
                        const ProductPlan& plan, float* acc) {
  using F = typename V::F;
  constexpr int W = V::W, N2 = N * N;
  alignas(64) float gi[N2 * W], y[N2 * W], tmp[N2 * W];
  F p[6];
  for (int a = 0; a < 6; ++a) p[a] = V::load(lanes[a]);
  for (int c = 0; c < N2; ++c) V::store(acc + c * W, V::set(c == 0 ? static_cast<float>(sh::kSqrt4Pi) : 0.0f));
  long long products = 0;
  for (std::size_t j = 0; j < b.size(); ++j) {
    F fl[N], sx, sy, sz;
    const F st = blocker_view<V, N>(vis, rule, p, b.cx[j], b.cy[j], b.cz[j], b.r[j], fl, sx, sy, sz);
    if (V::count(V::lt(V::set(0.0f), st)) == 0) continue;
    alignas(64) float stv[W];
    V::store(stv, st);
    for (std::size_t k = 0; k < cnt; ++k) products += stv[k] > 0.0f;  // padding lanes are not receivers
    basis_soa<V>(N, sx, sy, sz, y);
    for (int l = 0; l < N; ++l)
      for (int m = -l; m <= l; ++m) {
        const int k = l * l + l + m;
        V::store(gi + k * W, V::mul(fl[l], V::load(y + k * W)));
      }
    product_soa<V>(plan, acc, gi, tmp);
    for (int c = 0; c < N2 * W; ++c) acc[c] = tmp[c];
  }
  return products;
}

template <class V, int N>
long long product_range(const ZhTable& vis, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin, std::size_t end,
                        const BlockerList& b, const ProductPlan& plan, float* out) {
  constexpr int W = V::W, N2 = N * N;
  alignas(64) float lanes[6][W];
  alignas(64) float res[N2 * W];
  long long products = 0;
  for (std::size_t i0 = begin; i0 < end; i0 += W) {
    const std::size_t cnt = end - i0 < static_cast<std::size_t>(W) ? end - i0 : static_cast<std::size_t>(W);
    receiver_lanes<W>(rec, i0, cnt, lanes);
    products += product_block<V, N>(vis, rule, lanes, cnt, b, plan, res);
    for (std::size_t k = 0; k < cnt; ++k)
      for (int c = 0; c < N2; ++c) out[(i0 + k) * N2 + c] = res[c * W + k];
  }
  return products;
}

inline long long product_dispatch(int order, const ZhTable& vis, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                                  std::size_t end, const BlockerList& b, const ProductPlan& plan, float* out) {
  switch (order) {
    case 3: return product_range<Vec, 3>(vis, rule, rec, begin, end, b, plan, out);
    case 4: return product_range<Vec, 4>(vis, rule, rec, begin, end, b, plan, out);
    case 5: return product_range<Vec, 5>(vis, rule, rec, begin, end, b, plan, out);
    case 6: return product_range<Vec, 6>(vis, rule, rec, begin, end, b, plan, out);
    case 7: return product_range<Vec, 7>(vis, rule, rec, begin, end, b, plan, out);
    case 8: return product_range<Vec, 8>(vis, rule, rec, begin, end, b, plan, out);
    default: return 0;
  }
}
