// Private helpers shared by the proxy sources (sphere_fit.cpp, hierarchy.cpp, binding.cpp).
#pragma once

#include <glm/glm.hpp>
#include <functional>

#include "softgi/scene/scene.hpp"

namespace softgi::proxies::detail {

struct PowellResult {
  glm::dvec3 x{0.0};
  double f = 0.0;
  int evaluations = 0;
};
// Powell's direction-set method with Brent line minimisation (Press et al. 1992, Numerical Recipes in C, 2nd ed.,
// section 10.5), as paper 004 section 6.2/6.3 prescribe for the sphere centres. `step` is the initial
// length of the three coordinate directions; line minimisations stop at a relative bracket width
// line_tol (in units of the current direction's length); the method stops when a sweep reduces f by
// less than ftol relatively, after max_sweeps sweeps, or past max_evaluations.
PowellResult powell_minimize(const std::function<double(const glm::dvec3&)>& f, const glm::dvec3& x0, double step,
                             double ftol, double line_tol, int max_sweeps, int max_evaluations);

// The smallest float >= r (r finite, >= 0): radii computed in double from float centres stay
// conservative once stored as float.
float round_radius_up(double r);

}  // namespace softgi::proxies::detail
