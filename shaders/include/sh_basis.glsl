// Real SH basis by the polynomial recurrence of the CPU kernel (techniques/common/kernel_body.hpp):
// y_{l,+-m} = Q_l^m(z) {C_m, S_m}(x, y), C_m + i S_m = (x + i y)^m, Q from the uploaded constants.
// Expects SHEXP_BASIS_BINDING defined and softgi_shared.h included.
// A uniform block, not a storage buffer: every index into it is a constant (the recurrence below is
// written out), and drivers read such a uniform once for all lanes (llvmpipe loads a storage buffer
// lane by lane, with a bounds check each, even where the index is the same for all). std140 pads
// a float array's elements to 16 bytes, so the floats travel as vec4s.
layout(std140, set = 0, binding = SHEXP_BASIS_BINDING) uniform BasisConsts { vec4 basis_v[kBasisFloats / 4u]; };

float basis_c(uint i) { return basis_v[i >> 2u][i & 3u]; }

// The band l of coefficient q = l^2 + l + m. Loops over bands with an inner loop over each band's
// coefficients are written as one loop over q with this table: a loop with a constant trip count
// is unrolled where the nested one (its inner bounds depend on the outer index) may stay rolled
// (llvmpipe), leaving the per-coefficient arrays indexed at run time and kept in memory.
const uint kShBand[64] = uint[64](0u, 1u, 1u, 1u, 2u, 2u, 2u, 2u, 2u, 3u, 3u, 3u, 3u, 3u, 3u, 3u, 4u, 4u, 4u, 4u, 4u, 4u, 4u, 4u, 4u, 5u, 5u, 5u, 5u, 5u, 5u, 5u, 5u, 5u, 5u, 5u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 6u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u, 7u);
float basis_qmm(uint m) { return basis_c(kBasisQmm + m); }
float basis_a1(uint m) { return basis_c(kBasisA1 + m); }
float basis_A(uint l, uint m) { return basis_c(kBasisA + l * kAccumMaxOrder + m); }
float basis_B(uint l, uint m) { return basis_c(kBasisB + l * kAccumMaxOrder + m); }

// The same recurrence written out for every band l and order m below kAccumMaxOrder (8), each step
// under `if (l < ORDER)`. ORDER is a specialisation constant, so once specialised the conditions are
// constants and the dead steps vanish, leaving straight-line code with constant indices into C, S
// and the caller's arrays. Written out rather than looped because a driver may leave the loops over
// bands rolled even under [[unroll]] (llvmpipe, Mesa 22.3.6, does), and then every per-band array
// is indexed at run time and kept in memory: accumulate_log ran 3.5x slower so (bench/README.md).
// SH_BASIS_UNROLLED(ORDER) reads the unit direction `sh_dir` and, for each (l, m), m >= 0, expands
// the caller's SH_BASIS_PUT(l, m, q) with q = Q_l^m(z); the caller forms y_{l,+-m} = q {sh_C, sh_S}[m].
// Use it inside braces (it declares sh_C, sh_S, q_prev and qv).
#define SH_CS(m, ORDER)                                                 \
  if ((m) < (ORDER)) {                                                  \
    sh_C[m] = sh_C[(m) - 1u] * sh_dir.x - sh_S[(m) - 1u] * sh_dir.y;    \
    sh_S[m] = sh_S[(m) - 1u] * sh_dir.x + sh_C[(m) - 1u] * sh_dir.y;    \
  }
#define SH_Q_HEAD(m, ORDER) \
  if ((m) < (ORDER)) {      \
    float q_prev = 0.0, qv = basis_qmm(m); SH_BASIS_PUT(m, m, qv)
#define SH_Q_FIRST(l, m, ORDER)                       \
  if ((l) < (ORDER)) {                                \
    q_prev = qv;                                      \
    qv = basis_a1(m) * (sh_dir.z * qv);               \
    SH_BASIS_PUT(l, m, qv)                            \
  }
#define SH_Q_NEXT(l, m, ORDER)                                                            \
  if ((l) < (ORDER)) {                                                                    \
    const float q_next = basis_A(l, m) * (sh_dir.z * qv) - basis_B(l, m) * q_prev;        \
    q_prev = qv;                                                                          \
    qv = q_next;                                                                          \
    SH_BASIS_PUT(l, m, qv)                                                                \
  }
#define SH_BASIS_UNROLLED(ORDER)                                                                                          \
  float sh_C[kAccumMaxOrder], sh_S[kAccumMaxOrder];                                                                       \
  sh_C[0] = 1.0;                                                                                                          \
  sh_S[0] = 0.0;                                                                                                          \
  SH_CS(1u, ORDER) SH_CS(2u, ORDER) SH_CS(3u, ORDER) SH_CS(4u, ORDER) SH_CS(5u, ORDER) SH_CS(6u, ORDER) SH_CS(7u, ORDER)  \
  SH_Q_HEAD(0u, ORDER) SH_Q_FIRST(1u, 0u, ORDER) SH_Q_NEXT(2u, 0u, ORDER) SH_Q_NEXT(3u, 0u, ORDER)                        \
    SH_Q_NEXT(4u, 0u, ORDER) SH_Q_NEXT(5u, 0u, ORDER) SH_Q_NEXT(6u, 0u, ORDER) SH_Q_NEXT(7u, 0u, ORDER) }                 \
  SH_Q_HEAD(1u, ORDER) SH_Q_FIRST(2u, 1u, ORDER) SH_Q_NEXT(3u, 1u, ORDER) SH_Q_NEXT(4u, 1u, ORDER)                        \
    SH_Q_NEXT(5u, 1u, ORDER) SH_Q_NEXT(6u, 1u, ORDER) SH_Q_NEXT(7u, 1u, ORDER) }                                          \
  SH_Q_HEAD(2u, ORDER) SH_Q_FIRST(3u, 2u, ORDER) SH_Q_NEXT(4u, 2u, ORDER) SH_Q_NEXT(5u, 2u, ORDER)                        \
    SH_Q_NEXT(6u, 2u, ORDER) SH_Q_NEXT(7u, 2u, ORDER) }                                                                   \
  SH_Q_HEAD(3u, ORDER) SH_Q_FIRST(4u, 3u, ORDER) SH_Q_NEXT(5u, 3u, ORDER) SH_Q_NEXT(6u, 3u, ORDER)                        \
    SH_Q_NEXT(7u, 3u, ORDER) }                                                                                            \
  SH_Q_HEAD(4u, ORDER) SH_Q_FIRST(5u, 4u, ORDER) SH_Q_NEXT(6u, 4u, ORDER) SH_Q_NEXT(7u, 4u, ORDER) }                      \
  SH_Q_HEAD(5u, ORDER) SH_Q_FIRST(6u, 5u, ORDER) SH_Q_NEXT(7u, 5u, ORDER) }                                               \
  SH_Q_HEAD(6u, ORDER) SH_Q_FIRST(7u, 6u, ORDER) }                                                                        \
  SH_Q_HEAD(7u, ORDER) }

#ifdef SHEXP_BASIS_ORDER
// Y = y(s) for every band below SHEXP_BASIS_ORDER (the including shader's order, a specialisation
// constant declared before the include), by the recurrence above (the CPU kernel's basis_soa).
void sh_basis_eval(vec3 sh_dir, out float Y[kAccumMaxCoeffs]) {
#define SH_BASIS_PUT(l, m, q)                          \
  if ((m) == 0u) {                                     \
    Y[(l) * (l) + (l)] = (q);                          \
  } else {                                             \
    Y[(l) * (l) + (l) + (m)] = (q) * sh_C[m];          \
    Y[(l) * (l) + (l) - (m)] = (q) * sh_S[m];          \
  }
  SH_BASIS_UNROLLED(SHEXP_BASIS_ORDER)
#undef SH_BASIS_PUT
}
#endif
