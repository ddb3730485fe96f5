// Real SH basis by the polynomial recurrence of the CPU kernel (techniques/shexp/kernel_body.hpp):
// y_{l,+-m} = Q_l^m(z) {C_m, S_m}(x, y), C_m + i S_m = (x + i y)^m, Q from the uploaded constants.
// Expects SHEXP_BASIS_BINDING defined and softgi_shared.h included.
layout(std430, set = 0, binding = SHEXP_BASIS_BINDING) readonly buffer BasisConsts { float basis_c[]; };

float basis_qmm(uint m) { return basis_c[kBasisQmm + m]; }
float basis_a1(uint m) { return basis_c[kBasisA1 + m]; }
float basis_A(uint l, uint m) { return basis_c[kBasisA + l * kShexpMaxOrder + m]; }
float basis_B(uint l, uint m) { return basis_c[kBasisB + l * kShexpMaxOrder + m]; }
