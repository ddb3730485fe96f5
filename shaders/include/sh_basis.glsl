// Real SH basis by the polynomial recurrence of the CPU kernel (techniques/common/kernel_body.hpp):
// y_{l,+-m} = Q_l^m(z) {C_m, S_m}(x, y), C_m + i S_m = (x + i y)^m, Q from the uploaded constants.
// Expects SHEXP_BASIS_BINDING defined and softgi_shared.h included (and GL_EXT_control_flow_attributes
// enabled when SHEXP_BASIS_ORDER is defined).
layout(std430, set = 0, binding = SHEXP_BASIS_BINDING) readonly buffer BasisConsts { float basis_c[]; };

float basis_qmm(uint m) { return basis_c[kBasisQmm + m]; }
float basis_a1(uint m) { return basis_c[kBasisA1 + m]; }
float basis_A(uint l, uint m) { return basis_c[kBasisA + l * kAccumMaxOrder + m]; }
float basis_B(uint l, uint m) { return basis_c[kBasisB + l * kAccumMaxOrder + m]; }

#ifdef SHEXP_BASIS_ORDER
// Y = y(s) for every band below SHEXP_BASIS_ORDER (the including shader's order, a specialisation
// constant declared before the include), by the recurrence above (the CPU kernel's basis_soa).
void sh_basis_eval(vec3 s, out float Y[kAccumMaxCoeffs]) {
  float C[kAccumMaxOrder], S[kAccumMaxOrder];
  C[0] = 1.0;
  S[0] = 0.0;
  [[unroll]] for (uint m = 1; m < SHEXP_BASIS_ORDER; ++m) {
    C[m] = C[m - 1] * s.x - S[m - 1] * s.y;
    S[m] = S[m - 1] * s.x + C[m - 1] * s.y;
  }
  [[unroll]] for (uint m = 0; m < SHEXP_BASIS_ORDER; ++m) {
    float q_prev = 0.0, qv = basis_qmm(m);
    [[unroll]] for (uint l = m; l < SHEXP_BASIS_ORDER; ++l) {
      if (l == m + 1) {
        q_prev = qv;
        qv = basis_a1(m) * (s.z * qv);
      } else if (l > m + 1) {
        const float next = basis_A(l, m) * (s.z * qv) - basis_B(l, m) * q_prev;
        q_prev = qv;
        qv = next;
      }
      const uint i0 = l * l + l;
      if (m == 0) {
        Y[i0] = qv;
      } else {
        Y[i0 + m] = qv * C[m];
        Y[i0 - m] = qv * S[m];
      }
    }
  }
}
#endif
