// 1D Gauss-Legendre quadrature, used to build every table and reference in double.
#pragma once

#include <functional>
#include <vector>

namespace softgi::sh {

// n-point Gauss-Legendre nodes and weights on [-1, 1] (Newton iteration on P_n, to 1e-15).
// Exact for polynomials of degree <= 2n - 1. Cached per n; thread-safe.
struct GaussLegendre {
  std::vector<double> nodes, weights;
};
const GaussLegendre& gauss_legendre(int n);

// int_a^b f(x) dx with n-point Gauss-Legendre on each panel. Panels are graded geometrically towards
// `a` (smallest panel width `a_scale`, ratio 2) when 0 < a_scale < (b - a): resolves integrands with a
// feature of width a_scale at x = a (a sqrt kink, a near-singular peak) without a fine uniform grid.
double integrate(const std::function<double(double)>& f, double a, double b, int n = 24,
                 double a_scale = 0.0);

}  // namespace softgi::sh
