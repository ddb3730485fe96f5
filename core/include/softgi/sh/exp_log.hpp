// SH exponential and logarithm (paper 004 sections 4 and 5).
#pragma once

#include <span>
#include <string>
#include <vector>

#include "softgi/sh/sh.hpp"

namespace softgi::sh {

class ShTables;  // tables.hpp: OL coefficient table

enum class ExpMethod {
  PS,      // plain product series of degree p (eq. 17), products accumulated left to right
  PSStar,  // PS*-p: DC isolation (20), scaling/squaring (21), factored even/odd series (22)
  OL,      // optimal linear approximation (eqs. 23-24)
  HYB,     // scaling/squaring applied to OL (section 4.3)
  Exact,   // eigen-decomposition of the product matrix (eq. 28), double precision reference
};
const char* to_string(ExpMethod m);
// Parses "ps", "ps*", "psstar", "ol", "hyb", "exact" (case-insensitive); throws naming the value.
ExpMethod parse_exp_method(const std::string& name);

struct ExpStats {
  int squarings = 0;  // scaling/squaring steps applied
  int products = 0;   // general SH products
  int squares = 0;    // SH squares (including the squarings)
};

// Number of squarings the paper prescribes for scaling/squaring (section 4.1):
// p = max(0, floor(log2 ||f|| + 3)); 0 for ||f|| = 0.
int paper_squarings(double norm);

// Every method throws std::invalid_argument for NaN/Inf input (naming the coefficient) and
// std::overflow_error when the result cannot be represented (DC term beyond the type's range).
// f and out hold n*n coefficients; out must not alias f.
template <class T>
void exp_ps(int order, const T* f, int degree, T* out, ExpStats* stats = nullptr);
template <class T>
void exp_ps_star(int order, const T* f, int degree, T* out, ExpStats* stats = nullptr);
template <class T>
void exp_ol(const ShTables& tables, const T* f, T* out, ExpStats* stats = nullptr);
// HYB: OL applied to f^/2^s, then s squarings. max_norm = 0 (default) takes s from the paper's
// scaling rule, paper_squarings(||f^||), which puts ||f^||/2^s in [1/8, 1/4): paper 004 does not
// print HYB's rule, but its Figure 9 counts (1.88 squares per vertex for HYB, 1.78 squarings for
// PS*-2 on the same scene) match this rule. max_norm > 0 instead takes the fewest squarings with
// ||f^||/2^s <= max_norm (fewer squares, larger error; see docs/sh.md).
template <class T>
void exp_hyb(const ShTables& tables, const T* f, T* out, double max_norm = 0.0, ExpStats* stats = nullptr);
// eq. 28: g = 1 + R^T q(D) R f with M_f = R^T D R, q(x) = (e^x - 1)/x. Double only (Eigen, slow).
void exp_exact(int order, const double* f, double* out);
// eq. 10 by quadrature: projection of exp(f(s)). Not what the product-space methods approximate
// (they converge to eq. 28), but the true exponential of the reconstructed function.
void exp_projected(int order, const double* f, double* out);

struct ExpOptions {
  ExpMethod method = ExpMethod::HYB;
  int degree = 2;         // series degree for PS / PS*
  double hyb_max_norm = 0.0;  // 0: the paper's squaring rule
};
// Dispatcher. `tables` may be null for PS, PS*, Exact; OL and HYB need it (throws otherwise).
template <class T>
void exp(int order, const T* f, T* out, const ExpOptions& opt, const ShTables* tables,
         ExpStats* stats = nullptr);

// SH log by eigen inversion of exp (eqs. 30-32): M_g = R^T D R, eigenvalues clipped to
// max(D, threshold * max(D)), log(g) = R^T q'(D~) R (g - 1), q'(x) = log(x)/(x - 1).
// threshold 0.02 is the paper's value. Throws std::domain_error when max(D) <= 0 (g nowhere positive).
void log_eigen(int order, const double* g, double* out, double threshold = 0.02);

}  // namespace softgi::sh
